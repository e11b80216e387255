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

Examples::

    python benchmarks/static_fit.py --scene results/demo --out benchmarks/out
    python benchmarks/static_fit.py --quick            # shorter runs, small sweep
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
from anigs.static.fit import FitConfig, fit_static  # noqa: E402


def load_scene(scene: Path | None):
    """(images [H,W,3] list, cameras, points [P,3], colours [P,3], background, description)."""
    from anigs.images import load_inputs
    from anigs.sfm.model import load_points

    if scene is not None and (scene / "sfm" / "cameras.json").exists():
        img_dir = scene / "sfm" / "images"
        if not img_dir.is_dir():
            img_dir = scene / "capture" / "images"
        imgs, cams = load_inputs(img_dir, scene / "sfm" / "cameras.json")
        pts, cols = load_points(scene / "sfm" / "points.npz")
        bg = _capture_background(scene)
        return imgs, cams, pts, cols, bg, f"{scene} (SfM cameras and points)"
    from anigs.gaussians import load_ply
    from anigs.synth import write_capture

    tmp = Path(tempfile.mkdtemp(prefix="anigs_bench_static_"))
    print(f"no SfM outputs given: rendering the embedded demo capture to {tmp}")
    write_capture(None, tmp)
    imgs, cams = load_inputs(tmp / "images", tmp / "gt" / "cameras.json")
    g = load_ply(tmp / "gt" / "gaussians.ply")
    rng = np.random.default_rng(0)
    pts = g.means.numpy()[::6].astype(np.float64)
    pts = pts + rng.normal(0, 0.02, pts.shape)
    cols = g.rgb.clamp(0, 1).numpy()[::6]
    bg = _capture_background(tmp.parent, tmp / "gt" / "cameras.json")
    return imgs, cams, pts, cols, bg, "embedded demo capture, GT cameras, pseudo-SfM points"


def _capture_background(scene: Path, cams_json: Path | None = None) -> list[float] | None:
    import json

    for p in ([cams_json] if cams_json else []) + [scene / "capture" / "gt" / "cameras.json"]:
        if p is not None and p.exists():
            bg = json.loads(p.read_text()).get("background")
            if bg:
                return [float(x) for x in bg]
    return None


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
    default_budget = FitConfig.from_dict(base).densify.max_gaussians
    runs = [("default", 1.0, default_budget)]
    runs += [(f"res x{s:g}", s, default_budget) for s in scales if s != 1.0]
    runs += [(f"budget {b // 1000}k", 1.0, b) for b in budgets if b != default_budget]

    print(f"scene: {what}; {len(imgs)} images {cams[0].width}x{cams[0].height}, {len(pts)} points; "
          f"torch threads {torch.get_num_threads()}, cpus {os.cpu_count()}")
    args.out.mkdir(parents=True, exist_ok=True)
    rows, series, summary = [], {}, []
    for name, s, budget in runs:
        cfg_d = {**base, "densify": {**base.get("densify", {}), "max_gaussians": budget}}
        cfg = FitConfig.from_dict(cfg_d)
        im, cm = rescale(imgs, cams, s)
        t0 = time.perf_counter()
        g, m = fit_static(im, cm, pts, cols, cfg, progress=False)
        wall = time.perf_counter() - t0
        full = m["test_psnr"]
        if s != 1.0:  # a lower training resolution is judged on the full-resolution held-out views
            from anigs.static.fit import _to_params, evaluate, split_holdout

            _, test = split_holdout(len(imgs), cfg.holdout_every)
            bgt = torch.tensor(cfg.background, dtype=torch.float32)
            full = evaluate(_to_params(g, "cpu"), [imgs[i] for i in test], [cams[i] for i in test],
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
        print(f"{name:>12}: {cm[0].width}x{cm[0].height}, budget {budget}: held-out PSNR {m['test_psnr']:.2f} dB "
              f"({full:.2f} dB at full resolution), "
              f"train PSNR {m['train_psnr']:.2f} dB, {m['num_gaussians']} Gaussians, train {m['train_seconds']:.0f} s "
              f"(wall {wall:.0f} s)")
    print()
    print(f"{'run':>12} {'size':>8} {'budget':>7} {'iter':>6} {'seconds':>8} {'PSNR':>7} {'SSIM':>6} {'#G':>7}")
    for r in rows:
        print(f"{r['run']:>12} {r['width']:>4}x{r['height']:<3} {r['max_gaussians']:>7} {r['iteration']:>6} "
              f"{r['train_seconds']:>8.1f} {r['test_psnr']:>7.2f} {r['test_ssim']:>6.3f} {r['num_gaussians']:>7}")
    csv_path, png_path = args.out / "static_fit.csv", args.out / "static_fit.png"
    sum_path = args.out / "static_fit_summary.csv"
    from anigs.io import atomic_path

    for path, table in ((csv_path, rows), (sum_path, summary)):
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=list(table[0]))
                w.writeheader()
                w.writerows(table)
    with atomic_path(png_path) as tmp:
        draw_plot(tmp, series, f"static fit: held-out PSNR vs training time ({os.cpu_count()} cpus, shared)")
    print(f"\nwrote {csv_path}, {sum_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
