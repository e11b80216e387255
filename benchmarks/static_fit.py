"""Accuracy versus time of the static 3DGS fit: how long to train.

Runs ``anigs.static.fit.fit_static`` and records held-out PSNR at checkpoints against wall seconds
(training time, evaluation excluded; also process CPU seconds, a contention-free proxy), for the
default settings and for a sweep over image
resolution (judged on full-resolution held-out views too) and Gaussian budget. Prints a table
and writes ``static_fit.csv`` (curves), ``static_fit_summary.csv`` (one row per run) and
``static_fit.png`` (drawn with PIL; matplotlib is not a dependency).

Inputs, in order of preference:
  * ``--scene DIR`` with ``sfm/cameras.json``, ``sfm/points.npz`` and images (``sfm/images`` or
    ``capture/images``): the workflow's own outputs (e.g. ``results/demo``);
  * otherwise the embedded demo capture is rendered to a temporary folder and the ground-truth
    cameras are used with pseudo-SfM points (every 6th ground-truth mean + 2 cm noise), so the
    benchmark needs neither COLMAP nor a previous workflow run.

The step against the rasterizer (after the default run, on its fitted Gaussians): the fit's
own step time over its last evaluation interval at a constant Gaussian count (from the curve;
works with any version of the library), and, interleaved view by view, the median of the fit's
training step (``anigs.static.fit.train_step``: render, fused SSIM loss, backward, divergence
record, fused Adam) against the median of the rasterizer's forward+backward alone at the same
Gaussians, SH degree, resolution and views; wall and process CPU medians and their ratios. Also
per-part medians (loss forward+backward with the fused and with the reference SSIM, the
optimiser step). Written to ``static_fit_step.csv``.

Examples::

    python benchmarks/static_fit.py --scene results/demo --out benchmarks/out
    python benchmarks/static_fit.py --quick            # shorter runs, small sweep
    python benchmarks/static_fit.py --scene results/demo --iterations 1000 --no-sweep --threads 1
"""
from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # see anigs/stages/static.py

import argparse  # noqa: E402
import csv  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

from anigs.cameras import Camera  # noqa: E402
from anigs.static.fit import StaticConfig, fit_static  # noqa: E402


def load_scene(scene: Path | None):
    """(images [H,W,3] list, cameras, points [P,3], colours [P,3], background, description)."""
    from _pseudo_sfm import pseudo_sfm_points
    from anigs.images import load_inputs
    from anigs.stages.capture import Outputs as CaptureOutputs
    from anigs.stages.sfm import Outputs as SfmOutputs

    sfm = SfmOutputs(scene / "sfm") if scene is not None else None
    if sfm is not None and sfm.exists("cameras"):
        cap = CaptureOutputs(scene / "capture")
        img_dir = sfm.path("images") if sfm.path("images").is_dir() else cap.path("images")
        imgs, cams = load_inputs(img_dir, sfm.path("cameras"))
        pts, cols = sfm.points()
        return imgs, cams, pts, cols, _capture_background(cap), f"{scene} (SfM cameras and points)"
    from anigs.synth import write_capture

    tmp = Path(tempfile.mkdtemp(prefix="anigs_bench_static_"))
    print(f"no SfM outputs given: rendering the embedded demo capture to {tmp}")
    cap = CaptureOutputs(tmp)
    write_capture(None, cap)
    imgs, cams = load_inputs(cap.path("images"), cap.path("gt_cameras"))
    pts, cols = pseudo_sfm_points(cap)
    return imgs, cams, pts, cols, _capture_background(cap), "embedded demo capture, GT cameras, pseudo-SfM points"


def _capture_background(cap) -> list[float] | None:
    """The synthetic capture's background (None for photos)."""
    return cap.gt_background() if cap.exists("gt_cameras") else None


def _load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def rescale(imgs: list[torch.Tensor], cams: list[Camera], factor: float):
    if factor == 1.0:
        return imgs, cams
    from PIL import Image

    out_i, out_c = [], []
    for im, cam in zip(imgs, cams):
        w, h = max(8, round(cam.width * factor)), max(8, round(cam.height * factor))
        pil = Image.fromarray((im.numpy() * 255 + 0.5).astype(np.uint8)).resize((w, h), Image.LANCZOS)
        out_i.append(torch.from_numpy(np.asarray(pil, dtype=np.float32) / 255.0))
        out_c.append(cam.scaled(w, h))
    return out_i, out_c


def draw_plot(path: Path, series: dict[str, list[tuple[float, float]]], title: str) -> None:
    """Line plot of PSNR (y) against seconds (x) per series, with PIL."""
    from PIL import Image, ImageDraw

    W, H, L, R, T, B = 900, 560, 70, 230, 40, 50
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    pts = [p for s in series.values() for p in s if np.isfinite(p[1])]
    if not pts:
        img.save(path)
        return
    x1 = max(p[0] for p in pts) * 1.05 or 1.0
    y0 = np.floor(min(p[1] for p in pts)) - 1
    y1 = np.ceil(max(p[1] for p in pts)) + 1
    X = lambda x: L + (W - L - R) * x / x1
    Y = lambda y: H - B - (H - T - B) * (y - y0) / (y1 - y0)
    d.rectangle([L, T, W - R, H - B], outline="black")
    for k in range(6):
        xv, yv = x1 * k / 5, y0 + (y1 - y0) * k / 5
        d.line([X(xv), H - B, X(xv), H - B + 5], fill="black")
        d.text((X(xv) - 12, H - B + 8), f"{xv:.0f}", fill="black")
        d.line([L - 5, Y(yv), L, Y(yv)], fill="black")
        d.text((L - 40, Y(yv) - 6), f"{yv:.1f}", fill="black")
        d.line([L, Y(yv), W - R, Y(yv)], fill=(230, 230, 230))
    d.text((L + 200, H - 20), "training wall seconds", fill="black")
    d.text((8, T - 25), "held-out PSNR (dB)", fill="black")
    d.text((L + 150, 10), title, fill="black")
    palette = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
               (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]
    for i, (name, s) in enumerate(series.items()):
        col = palette[i % len(palette)]
        xy = [(X(x), Y(y)) for x, y in s if np.isfinite(y)]
        if len(xy) > 1:
            d.line(xy, fill=col, width=2)
        for x, y in xy:
            d.ellipse([x - 3, y - 3, x + 3, y + 3], fill=col)
        d.line([W - R + 15, T + 15 + 18 * i, W - R + 40, T + 15 + 18 * i], fill=col, width=3)
        d.text((W - R + 45, T + 9 + 18 * i), name, fill="black")
    img.save(path)


def _median_ms(xs: list[float]) -> float:
    return float(np.median(xs)) * 1e3


def step_vs_raster(g, imgs: list[torch.Tensor], cams: list[Camera], cfg: StaticConfig, curve: list[dict],
                   repeat: int) -> list[dict]:
    """Rows (what, wall ms, CPU ms, ratio to the rasterizer) comparing the fit's step with the
    rasterizer's forward+backward at the fitted Gaussians (see the module docstring)."""
    import anigs.static.fit as F
    from anigs.render import rasterize

    dev = torch.device("cpu")
    _, test = F.split_holdout(len(imgs), cfg.holdout_every)
    train = [i for i in range(len(imgs)) if i not in set(test)]
    deg = g.sh_degree
    bg = torch.tensor(cfg.background, dtype=torch.float32)
    mats = {i: (cams[i].torch_viewmat(dev), cams[i].torch_K(dev)) for i in train}
    leaves = [t.detach().clone().requires_grad_(True) for t in (g.means, g.quats, g.scales, g.opacities, g.sh)]
    gen = torch.Generator().manual_seed(0)
    H, W = imgs[train[0]].shape[:2]
    upstream = torch.rand(H, W, 3, generator=gen) * 1e-3  # a fixed image gradient

    def raster(i: int) -> None:
        rgb, _, _ = rasterize(*leaves, *mats[i], cams[i].width, cams[i].height, sh_degree=deg, background=bg,
                              backend=cfg.backend)
        rgb.backward(upstream)
        for t in leaves:
            t.grad = None

    fns = {"rasterizer forward+backward": raster}
    has_step = hasattr(F, "train_step")
    if has_step:
        params = F.to_params(g.detach(), dev)
        params = {k: torch.nn.Parameter(v.detach().clone()) for k, v in params.items()}  # trained in place
        lr = {"means": cfg.lr_means_final, "quats": cfg.lr_quats, "log_scales": cfg.lr_scales,
              "opacity_logits": cfg.lr_opacity, "sh_dc": cfg.lr_sh_dc, "sh_rest": cfg.lr_sh_rest}
        opt = F.make_optimizer(params, lr)
        guard = F.DivergenceGuard(opt, list(params), dev)

        def step(i: int) -> None:
            F.train_step(params, opt, cams[i], imgs[i], deg, bg, cfg.backend, cfg.ssim_weight, mats=mats[i],
                         guard=guard, step=1)

        from anigs.ssim import fused_ssim, ssim

        pred = {i: (imgs[i] + 0.05 * torch.randn(imgs[i].shape, generator=gen)).clamp(0, 1) for i in train}

        def loss_with(ssim_fn):
            def run(i: int) -> None:
                x = pred[i].clone().requires_grad_(True)
                w = cfg.ssim_weight
                ((1 - w) * (x - imgs[i]).abs().mean() + w * (1 - ssim_fn(x, imgs[i]))).backward()
            return run

        for p in params.values():
            p.grad = torch.zeros_like(p)

        def adam(i: int) -> None:
            opt.step()

        fns = {"training step (train_step)": step, **fns, "loss fwd+bwd, fused SSIM": loss_with(fused_ssim),
               "loss fwd+bwd, reference SSIM": loss_with(ssim)}
    wall: dict[str, list[float]] = {k: [] for k in fns}
    cpu: dict[str, list[float]] = {k: [] for k in fns}
    for r in range(repeat + 2):  # two warm-up rounds
        i = train[r % len(train)]
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn(i)
            if r >= 2:
                wall[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
    if has_step:  # the optimiser on its own, after the others (it needs gradients in place)
        for p in params.values():
            p.grad = torch.zeros_like(p)
        wall["Adam step"], cpu["Adam step"] = [], []
        for r in range(repeat + 2):
            t0, c0 = time.perf_counter(), time.process_time()
            opt.step()
            if r >= 2:
                wall["Adam step"].append(time.perf_counter() - t0)
                cpu["Adam step"].append(time.process_time() - c0)
    rw = _median_ms(wall["rasterizer forward+backward"])
    rc = _median_ms(cpu["rasterizer forward+backward"])
    rows = []
    # the fit's own steps over the last evaluation interval (constant Gaussian count)
    a, b = (curve[-2], curve[-1]) if len(curve) >= 2 else (None, None)
    if a is not None and a["num_gaussians"] == b["num_gaussians"] == g.num and b["iteration"] > a["iteration"]:
        n = b["iteration"] - a["iteration"]
        fw = (b["train_seconds"] - a["train_seconds"]) / n * 1e3
        fc = (b["train_cpu_seconds"] - a["train_cpu_seconds"]) / n * 1e3
        rows.append({"what": f"fit, mean step over iterations {a['iteration']}-{b['iteration']}",
                     "wall_ms": fw, "cpu_ms": fc, "wall_ratio": fw / rw, "cpu_ratio": fc / rc})
    for name in wall:
        w, c = _median_ms(wall[name]), _median_ms(cpu[name])
        rows.append({"what": name, "wall_ms": w, "cpu_ms": c, "wall_ratio": w / rw, "cpu_ratio": c / rc})
    for r in rows:
        r.update(num_gaussians=g.num, size=f"{W}x{H}", sh_degree=deg, repeat=repeat)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=None, help="workflow results folder of a scene (has sfm/)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/out"))
    ap.add_argument("--params", default=None, help="static config JSON applied to every run")
    ap.add_argument("--iterations", type=int, default=None, help="override iterations for every run")
    ap.add_argument("--eval-every", type=int, default=250)
    ap.add_argument("--resolutions", default="0.5,1.0", help="image scale factors for the sweep")
    ap.add_argument("--budgets", default="15000,30000,60000", help="max_gaussians values for the sweep")
    ap.add_argument("--quick", action="store_true", help="1000 iterations, scales 0.5,1.0, budgets 15000,30000")
    ap.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    ap.add_argument("--no-sweep", action="store_true", help="the default run only (and the step comparison)")
    ap.add_argument("--step-repeat", type=int, default=30,
                    help="interleaved repetitions of the step-versus-rasterizer comparison (0 = skip it)")
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    from anigs.cli import parse_params

    base = parse_params(args.params)
    if args.iterations or args.quick:
        base["iterations"] = args.iterations or 1000
    base["eval_every"] = args.eval_every
    imgs, cams, pts, cols, bg, what = load_scene(args.scene)
    if bg is not None and "background" not in base:
        base["background"] = bg
    scales = [float(s) for s in args.resolutions.split(",") if s]
    budgets = [int(b) for b in args.budgets.split(",") if b]
    if args.quick:
        scales, budgets = [0.5, 1.0], [15000, 30000]
    default_budget = StaticConfig.from_dict(base).densify.max_gaussians
    runs = [("default", 1.0, default_budget)]
    if not args.no_sweep:
        runs += [(f"res x{s:g}", s, default_budget) for s in scales if s != 1.0]
        runs += [(f"budget {b // 1000}k", 1.0, b) for b in budgets if b != default_budget]

    print(f"scene: {what}; {len(imgs)} images {cams[0].width}x{cams[0].height}, {len(pts)} points; "
          f"torch threads {torch.get_num_threads()}, cpus {os.cpu_count()}; load average {_load()}")
    args.out.mkdir(parents=True, exist_ok=True)
    rows, series, summary, step_rows = [], {}, [], []
    for name, s, budget in runs:
        cfg_d = {**base, "densify": {**base.get("densify", {}), "max_gaussians": budget}}
        cfg = StaticConfig.from_dict(cfg_d)
        im, cm = rescale(imgs, cams, s)
        t0 = time.perf_counter()
        g, m = fit_static(im, cm, pts, cols, cfg, progress=False)
        wall = time.perf_counter() - t0
        full = m["test_psnr"]
        if s != 1.0:  # a lower training resolution is judged on the full-resolution held-out views
            from anigs.static.fit import to_params, evaluate, split_holdout

            _, test = split_holdout(len(imgs), cfg.holdout_every)
            bgt = torch.tensor(cfg.background, dtype=torch.float32)
            full = evaluate(to_params(g, "cpu"), [imgs[i] for i in test], [cams[i] for i in test],
                            g.sh_degree, bgt, cfg.backend)["psnr"]
        summary.append({"run": name, "size": f"{cm[0].width}x{cm[0].height}", "max_gaussians": budget,
                        "num_gaussians": m["num_gaussians"], "train_seconds": round(m["train_seconds"], 1),
                        "train_cpu_seconds": round(m["train_cpu_seconds"], 1), "test_psnr": round(m["test_psnr"], 3),
                        "test_psnr_full_res": round(full, 3), "train_psnr": round(m["train_psnr"], 3)})
        for r in m["curve"]:
            rows.append({"run": name, "width": cm[0].width, "height": cm[0].height, "max_gaussians": budget,
                         "iteration": r["iteration"], "train_seconds": round(r["train_seconds"], 2),
                         "train_cpu_seconds": round(r["train_cpu_seconds"], 2),
                         "test_psnr": round(r["test_psnr"], 3), "test_ssim": round(r["test_ssim"], 4),
                         "num_gaussians": r["num_gaussians"]})
        series[f"{name} ({cm[0].width}x{cm[0].height})"] = [(r["train_seconds"], r["test_psnr"]) for r in m["curve"]]
        if name == "default" and args.step_repeat > 0:
            step_rows = step_vs_raster(g, im, cm, cfg, m["curve"], args.step_repeat)
            if m.get("step_ms_median_final") is not None:
                print(f"fit: median step {m['step_ms_median']:.1f} ms, {m['step_ms_median_final']:.1f} ms from "
                      f"iteration {m['final_steps_from']} (constant Gaussian count)")
        print(f"{name:>12}: {cm[0].width}x{cm[0].height}, budget {budget}: held-out PSNR {m['test_psnr']:.2f} dB "
              f"({full:.2f} dB at full resolution), "
              f"train PSNR {m['train_psnr']:.2f} dB, {m['num_gaussians']} Gaussians, train {m['train_seconds']:.0f} s "
              f"(wall {wall:.0f} s)")
    print()
    print(f"{'run':>12} {'size':>8} {'budget':>7} {'iter':>6} {'seconds':>8} {'PSNR':>7} {'SSIM':>6} {'#G':>7}")
    for r in rows:
        print(f"{r['run']:>12} {r['width']:>4}x{r['height']:<3} {r['max_gaussians']:>7} {r['iteration']:>6} "
              f"{r['train_seconds']:>8.1f} {r['test_psnr']:>7.2f} {r['test_ssim']:>6.3f} {r['num_gaussians']:>7}")
    if step_rows:
        r0 = step_rows[0]
        print(f"\nstep versus rasterizer: {r0['num_gaussians']} Gaussians, {r0['size']}, SH degree {r0['sh_degree']}, "
              f"{r0['repeat']} interleaved repetitions, torch threads {torch.get_num_threads()}, "
              f"load average {_load()}")
        print(f"{'':>42} {'wall ms':>8} {'CPU ms':>8} {'x raster (wall)':>16} {'x raster (CPU)':>15}")
        for r in step_rows:
            print(f"{r['what']:>42} {r['wall_ms']:>8.2f} {r['cpu_ms']:>8.2f} {r['wall_ratio']:>16.2f} "
                  f"{r['cpu_ratio']:>15.2f}")
    csv_path, png_path = args.out / "static_fit.csv", args.out / "static_fit.png"
    sum_path = args.out / "static_fit_summary.csv"
    from anigs.io import atomic_path

    tables = [(csv_path, rows), (sum_path, summary)]
    if step_rows:
        tables.append((args.out / "static_fit_step.csv", [{k: (round(v, 3) if isinstance(v, float) else v)
                                                            for k, v in r.items()} for r in step_rows]))
    for path, table in tables:
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=list(table[0]))
                w.writeheader()
                w.writerows(table)
    with atomic_path(png_path) as tmp:
        draw_plot(tmp, series, f"static fit: held-out PSNR vs training time ({os.cpu_count()} cpus, shared)")
    print(f"\nwrote {', '.join(str(p) for p, _ in tables)} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
