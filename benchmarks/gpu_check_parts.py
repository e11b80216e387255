"""The measured parts of ``benchmarks/gpu_check.sh``, one subcommand each; each writes one JSON file.

    python benchmarks/gpu_check_parts.py env     OUT.json
    python benchmarks/gpu_check_parts.py capture OUT.json --dir D [--small]
    python benchmarks/gpu_check_parts.py static  OUT.json --dir D --device cuda --iterations 1000 [--ply P]
    python benchmarks/gpu_check_parts.py agree   OUT.json --dir D --ply P --device cuda
    python benchmarks/gpu_check_parts.py ltx     OUT.json --device cuda [--model D] [--small]
    python benchmarks/gpu_check_parts.py update  OUT.json --device cuda --steps 120 [--small]

Scene: the demo's synthetic capture (``config/scenes/demo.yaml``: 48 photos at 320x240 of a
30k-Gaussian garden), its ground-truth cameras and pseudo-SfM points (every 6th ground-truth
mean plus 2 cm noise), so that the static fit needs neither COLMAP nor the workflow. ``--small``
(the CPU rehearsal) shrinks every size. ``--device`` is ``cuda`` on the GPU machine; ``cpu``
rehearses the same code on the CPU (the gsplat comparison then uses the torch backend).
"""
from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import torch  # noqa: E402

# image and gradient agreement asked of gsplat against the CPU kernel (see the module docstring)
MIN_PSNR_DB = 40.0
MIN_GRAD_COSINE = 0.99
MAX_GRAD_REL = 0.1


def _sync(dev: torch.device) -> None:
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)


def _version(mod: str) -> str | None:
    try:
        from importlib.metadata import version

        return version(mod)
    except Exception:  # noqa: BLE001 - absent or odd metadata: reported as missing
        return None


def part_env(args) -> dict:
    """Machine, GPU and package versions."""
    import os
    import shutil
    import subprocess

    out = {"python": platform.python_version(), "torch": torch.__version__, "cuda_available": torch.cuda.is_available(),
           "cpu_count": os.cpu_count(), "torch_threads": torch.get_num_threads()}
    if torch.cuda.is_available():
        p = torch.cuda.get_device_properties(0)
        out.update(gpu=p.name, capability=f"{p.major}.{p.minor}", gpu_mem_gib=round(p.total_memory / 2**30, 1),
                   torch_cuda=torch.version.cuda)
    nvcc = shutil.which("nvcc")
    if nvcc:
        v = subprocess.run([nvcc, "--version"], capture_output=True, text=True).stdout.strip().splitlines()
        out["nvcc"] = v[-1] if v else "?"
    for name in ("gsplat", "diffusers", "transformers", "snakemake", "pycolmap", "opencv-python-headless",
                 "opencv-contrib-python-headless", "imageio-ffmpeg", "jsonschema", "numpy"):
        out[f"pkg:{name}"] = _version(name)
    return out


def _synth_cfg(small: bool):
    import yaml

    from anigs.synth.capture import SynthConfig

    d = yaml.safe_load((ROOT / "config" / "scenes" / "demo.yaml").read_text())["synthetic"]
    if small:
        d["scene"] = {**d.get("scene", {}), "num_gaussians": 3000}
        d["capture"] = {**d.get("capture", {}), "num_images": 12, "width": 96, "height": 72}
    return SynthConfig.from_dict(d)


def part_capture(args) -> dict:
    """Render the demo capture (ground truth at t=0) into ``--dir``."""
    from anigs.stages.capture import Outputs as CaptureOutputs
    from anigs.synth import write_capture

    t0 = time.perf_counter()
    summary = write_capture(_synth_cfg(args.small), CaptureOutputs(args.dir))
    return {"seconds": time.perf_counter() - t0, "images": len(summary.get("images", [])) or summary.get("num_images")}


def _load_capture(d: Path):
    """(images, cameras, points [P,3], colours [P,3], background) of a capture written by ``capture``."""
    from anigs.images import load_inputs
    from _pseudo_sfm import pseudo_sfm_points
    from anigs.stages.capture import Outputs as CaptureOutputs

    cap = CaptureOutputs(d)
    imgs, cams = load_inputs(cap.path("images"), cap.path("gt_cameras"))
    pts, cols = pseudo_sfm_points(cap)
    return imgs, cams, pts, cols, cap.gt_background() or [0.0, 0.0, 0.0]


def part_static(args) -> dict:
    """The static fit on ``--device`` (the demo's settings: 1000 iterations) with held-out PSNR every 100."""
    from anigs.static.fit import StaticConfig, fit_static

    imgs, cams, pts, cols, bg = _load_capture(Path(args.dir))
    backend = args.backend
    cfg = StaticConfig(iterations=args.iterations, background=tuple(bg), device=args.device, backend=backend,
                    eval_every=args.eval_every)
    g, m = fit_static(imgs, cams, pts, cols, cfg, progress=False)
    if args.ply:
        g.save_ply(args.ply)
    keep = ("test_psnr", "train_psnr", "num_gaussians", "iterations", "seconds", "train_seconds",
            "step_ms_median", "step_ms_median_final", "torch_threads")
    return {**{k: m.get(k) for k in keep}, "device": args.device, "backend": backend,
            "curve": [{k: r[k] for k in ("iteration", "test_psnr", "train_seconds", "num_gaussians")} for r in m["curve"]]}


def _render_grads(g, cam, dev: torch.device, backend: str, bg: list[float], weights):
    from anigs.render import rasterize

    leaves = [t.detach().to(dev).clone().requires_grad_(True) for t in (g.means, g.quats, g.scales, g.opacities, g.sh)]
    rgb, alpha, _ = rasterize(*leaves, cam.torch_viewmat(dev), cam.torch_K(dev), cam.width, cam.height,
                              sh_degree=g.sh_degree, background=torch.tensor(bg, device=dev), backend=backend)
    wr, wa = (w.to(dev) for w in weights)
    ((rgb * wr).sum() + (alpha * wa).sum()).backward()
    _sync(dev)
    return rgb.detach().cpu(), [t.grad.detach().cpu() for t in leaves]


def _save_comparison(path: Path, a: torch.Tensor, b: torch.Tensor) -> None:
    """PNG of images [H,W,3]: a | b | 10 x |a - b|."""
    from PIL import Image

    strip = torch.cat([a, b, (10 * (a - b).abs())], dim=1).clamp(0, 1)
    Image.fromarray((strip.numpy() * 255 + 0.5).astype(np.uint8)).save(path)


def part_agree(args) -> dict:
    """gsplat (CUDA) against the CPU kernel on a fitted model: images (PSNR) and gradients per view."""
    from anigs.gaussians import load_ply
    from anigs.images import load_inputs
    from anigs.metrics.image import psnr
    from anigs.stages.capture import Outputs as CaptureOutputs

    from anigs.device import get_device

    dev = get_device(args.device)
    fast = "gsplat" if dev.type == "cuda" else "torch"  # the CPU rehearsal: the torch backend stands in
    g = load_ply(args.ply)
    cap = CaptureOutputs(args.dir)
    _, cams = load_inputs(cap.path("images"), cap.path("gt_cameras"))
    bg = cap.gt_background() or [0.0, 0.0, 0.0]
    names = ["means", "quats", "scales", "opacities", "sh"]
    rows, worst = [], {n: (1.0, 0.0) for n in names}
    gen = torch.Generator().manual_seed(0)
    for cam in cams[:: max(1, len(cams) // args.views)][: args.views]:
        weights = (torch.randn(cam.height, cam.width, 3, generator=gen), torch.randn(cam.height, cam.width, generator=gen))
        t0 = time.perf_counter()
        rgb_f, grads_f = _render_grads(g, cam, dev, fast, bg, weights)
        t_fast = time.perf_counter() - t0
        t0 = time.perf_counter()
        rgb_c, grads_c = _render_grads(g, cam, torch.device("cpu"), "cpu", bg, weights)
        t_cpu = time.perf_counter() - t0
        row = {"view": cam.name, "psnr": float(psnr(rgb_f.clamp(0, 1), rgb_c.clamp(0, 1))),
               "seconds_fast": t_fast, "seconds_cpu": t_cpu}
        for n, a, b in zip(names, grads_f, grads_c):
            cos = float(torch.nn.functional.cosine_similarity(a.flatten().double(), b.flatten().double(), dim=0))
            rel = float((a - b).norm() / b.norm().clamp_min(1e-30))
            finite = bool(torch.isfinite(a).all())
            row[n] = {"cos": cos, "rel": rel, "finite": finite}
            worst[n] = (min(worst[n][0], cos if finite else -1.0), max(worst[n][1], rel if finite else math.inf))
        rows.append(row)
        if args.png and len(rows) == 1:
            _save_comparison(args.png, rgb_f, rgb_c)
    min_psnr = min(r["psnr"] for r in rows)
    grads_ok = all(c >= MIN_GRAD_COSINE and r <= MAX_GRAD_REL for c, r in worst.values())
    return {"backend": fast, "model": str(args.ply), "gaussians": g.num, "views": len(rows), "min_psnr": min_psnr,
            "mean_psnr": float(np.mean([r["psnr"] for r in rows])),
            "worst_grad": {n: {"min_cos": c, "max_rel": r} for n, (c, r) in worst.items()},
            "tolerance": {"psnr_db": MIN_PSNR_DB, "grad_cos": MIN_GRAD_COSINE, "grad_rel": MAX_GRAD_REL},
            "pass": bool(min_psnr >= MIN_PSNR_DB and grads_ok), "rows": rows}


def part_ltx(args) -> dict:
    """The LTX-Video prior (tiny random weights) on ``--device``: dtype, refine and SDS timings."""
    from anigs.refine.prior.ltx import LTXPrior
    from anigs.refine.prior.ltx_tiny import save_tiny_random_stack

    t0 = time.perf_counter()
    model = next((m for m in (args.model, args.model / "model") if (m / "model_index.json").exists()), None)
    if model is None:  # not written beforehand: save_tiny_random_stack returns the folder it wrote
        model = save_tiny_random_stack(args.model)
    t_build = time.perf_counter() - t0
    prior = LTXPrior({"model_path": str(model), "device": args.device, "max_sequence_length": 16, "steps": 8})
    T, H, W = (9, 32, 48) if args.small else (25, 192, 256)  # the demo's clips: 25 frames at 256x192
    clip = np.random.default_rng(0).random((T, H, W, 3)).astype(np.float32)
    dev = prior.device
    t0 = time.perf_counter()
    prior.load()
    t_load = time.perf_counter() - t0
    prior.refine(clip, None, "trees sway", seed=0, strength=0.5)  # warm-up
    _sync(dev)
    t0 = time.perf_counter()
    out = prior.refine(clip, None, "trees sway", seed=1, strength=0.5)
    _sync(dev)
    t_refine = time.perf_counter() - t0
    sigmas = prior.last_info.get("sigmas")  # the SDS call below replaces last_info
    coeffs = torch.zeros(5, device=dev, requires_grad=True)
    sub = (torch.from_numpy(clip[:5]).to(dev) * (1 + coeffs[:, None, None, None])).clamp(0, 1)
    t0 = time.perf_counter()
    loss = prior.sds_loss(sub, "trees sway", torch.Generator().manual_seed(0))
    loss.backward()
    _sync(dev)
    t_sds = time.perf_counter() - t0
    ok = bool(np.isfinite(out).all() and out.shape == clip.shape and torch.isfinite(loss)
              and torch.isfinite(coeffs.grad).all())
    peak = torch.cuda.max_memory_allocated(dev) / 2**20 if dev.type == "cuda" else None
    return {"device": str(dev), "dtype": str(prior.dtype).replace("torch.", ""), "clip": [T, H, W],
            "sigmas": sigmas, "build_seconds": t_build, "load_seconds": t_load,
            "refine_seconds": t_refine, "sds_seconds": t_sds, "finite": ok, "peak_gpu_mib": peak}


def _update_scene(n: int, dyn_frac: float, views: int, w: int, h: int, T: int):
    """N Gaussians in a 4 x 4 x 1.5 box, a random dynamic fraction, ``views`` cameras on a ring."""
    from anigs.animate.frames import render_frame
    from anigs.animate.update import ViewData
    from anigs.cameras import Camera, intrinsics_from_fov, look_at
    from anigs.gaussians import Gaussians

    g = torch.Generator().manual_seed(0)
    pts = torch.rand(n, 3, generator=g) * torch.tensor([4.0, 4.0, 1.5]) - torch.tensor([2.0, 2.0, 0.0])
    scales = torch.exp(torch.empty(n).uniform_(math.log(0.02), math.log(0.05), generator=g))
    G = Gaussians.from_points(pts, torch.rand(n, 3, generator=g), scales, opacity=0.6)
    mask = torch.rand(n, generator=g) < dyn_frac
    cams = [Camera(intrinsics_from_fov(60, w, h), look_at((5 * math.cos(a), 5 * math.sin(a), 2.0), (0, 0, 0.5)), w, h,
                   f"v{k}") for k, a in enumerate(2 * math.pi * k / views for k in range(views))]
    with torch.no_grad():
        data = [ViewData(c, render_frame(G, None, c, 0)[None].repeat(T, 1, 1, 1)) for c in cams]
    return G, mask, data


def part_update(args) -> dict:
    """One round's model update (the demo's settings: 120 steps, K = 12) on ``--device``."""
    from anigs.animate.update import run_update
    from anigs.animate.config import UpdateConfig

    size = (3000, 0.3, 3, 64, 48, 9) if args.small else (30_000, 0.3, 8, 256, 192, 25)
    G, mask, views = _update_scene(*size)
    ucfg = dict(num_bases=12, views_per_step=2, cano_views_per_step=1, lambda_cano=0.1, seed=0, device=args.device,
                backend=args.backend, spatial_lr_scale=1.0)
    run_update(G, mask, views, UpdateConfig(steps=1, **ucfg), progress=False)  # warm-up (kernels, allocator)
    t0 = time.perf_counter()
    res = run_update(G, mask, views, UpdateConfig(steps=args.steps, **ucfg), progress=False)
    wall = time.perf_counter() - t0
    losses = [h["loss"] for h in res.history if "loss" in h]
    return {"device": args.device, "backend": args.backend, "gaussians": size[0], "dynamic": int(mask.sum()), "views": size[2],
            "size": f"{size[3]}x{size[4]}", "frames": size[5], "steps": res.steps, "seconds": wall,
            "steps_per_s": res.steps / max(res.seconds, 1e-9), "first_loss": losses[0] if losses else None,
            "last_loss": losses[-1] if losses else None,
            "finite": all(bool(torch.isfinite(p).all()) for p in res.deformation.parameters())}


PARTS = {"env": part_env, "capture": part_capture, "static": part_static, "agree": part_agree, "ltx": part_ltx,
         "update": part_update}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("part", choices=sorted(PARTS))
    ap.add_argument("out", type=Path, help="JSON file to write")
    ap.add_argument("--dir", type=Path, help="capture folder (capture, static, agree)")
    ap.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N (anigs.device.get_device)")
    ap.add_argument("--backend", default="auto", help="static, update: the rasterizer backend")
    ap.add_argument("--iterations", type=int, default=1000)
    ap.add_argument("--eval-every", type=int, default=100)
    ap.add_argument("--ply", type=Path, help="static: where the fitted model goes; agree: the model to render")
    ap.add_argument("--views", type=int, default=8, help="agree: views compared")
    ap.add_argument("--png", type=Path, help="agree: the first view, fast | CPU kernel | 10x difference")
    ap.add_argument("--model", type=Path, default=Path("/tmp/anigs-gpu-check/ltx-tiny"), help="ltx: where save_tiny_random_stack wrote (or writes) the tiny stack")
    ap.add_argument("--steps", type=int, default=120, help="update: optimisation steps")
    ap.add_argument("--small", action="store_true", help="small sizes (the CPU rehearsal)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = PARTS[args.part](args)
    res["part_seconds"] = time.perf_counter() - t0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=1, default=float))
    print(json.dumps({k: v for k, v in res.items() if k not in ("rows", "curve")}, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
