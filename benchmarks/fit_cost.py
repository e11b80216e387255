"""What a static-fit step costs against the photo size and the Gaussian count, part by part.

    python benchmarks/fit_cost.py --sfm RESULTS/photos/sfm --ply RESULTS/photos/static/canonical.ply
        [--scales 0.25,0.5,0.75,1.0] [--gaussians 0,100000] [--reps 12] [--threads 2]

On a capture's SfM cameras and photos, with a fitted model (``--ply``; ``--gaussians N`` grows or
thins it to N by copying rows with a small jitter, 0: as it is), times the parts of one training
step of :func:`anigs.static.fit.train_step` view by view: the render, the loss (L1 + fused SSIM),
the backward of both, the densification statistics and the fused Adam step;
medians over ``--reps`` steps of wall and process CPU milliseconds. Prints a Markdown table and the
least-squares fit of the step's wall and CPU seconds to ``a + b * pixels + c * Gaussians + d * pixels *
Gaussians`` (the cost model of :class:`anigs.static.budget.StepCost`).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, (time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3


def main() -> None:
    import numpy as np
    import torch
    from _scaled_capture import load_sfm_capture, scaled_view

    from anigs.gaussians import load_ply
    from anigs.static.densify import DensifyState, update_state
    from anigs.static.evaluate import render_params, loss_fn
    from anigs.static.init import to_params, make_optimizer

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True)
    ap.add_argument("--ply", required=True)
    ap.add_argument("--scales", default="0.25,0.5,0.75,1.0")
    ap.add_argument("--gaussians", default="0")
    ap.add_argument("--reps", type=int, default=12)
    args, _, imgs, cams = load_sfm_capture(ap)
    base = load_ply(args.ply)
    gen = torch.Generator().manual_seed(0)
    rows = []
    print("| size | pixels | Gaussians | step wall ms | step CPU ms | render | loss | backward | densify stats | Adam |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n_want in [int(x) for x in args.gaussians.split(",")]:
        g = base
        if n_want and n_want != g.num:
            idx = torch.arange(n_want) % g.num
            jitter = torch.randn(n_want, 3, generator=gen) * g.log_scales.exp()[idx].mean(1, keepdim=True) * 0.3
            g = type(g)(g.means[idx] + jitter, g.quats[idx], g.log_scales[idx], g.opacity_logits[idx], g.sh[idx])
        for scale in [float(s) for s in args.scales.split(",")]:
            params = to_params(g, torch.device("cpu"))
            opt = make_optimizer(params, {k: 1e-4 for k in params})
            views = []
            for im, c in list(zip(imgs, cams))[: args.reps]:
                x, cs = scaled_view(im, c, scale, min_side=8)
                views.append((x.contiguous(), cs, (cs.torch_viewmat(), cs.torch_K())))
            parts = {k: [] for k in ("step", "step_cpu", "render", "loss", "backward", "stats", "adam")}
            state = DensifyState.empty(g.num)
            for rep in range(len(views) + 2):  # two warm-up steps
                target, cam, mats = views[rep % len(views)]
                t0, c0 = time.perf_counter(), time.process_time()
                (rgb, _, meta), tr, _ = _timed(lambda: render_params(params, cam, 3, torch.zeros(3), "auto", mats))
                meta["means2d"].retain_grad()
                loss, tl1, _ = _timed(lambda: loss_fn(rgb, target, 0.2))
                _, tb, _ = _timed(lambda: loss.backward())
                _, ts, _ = _timed(lambda: update_state(state, meta, cam.width, cam.height))
                _, ta, _ = _timed(lambda: (opt.step(), opt.zero_grad(set_to_none=True)))
                if rep >= 2:
                    parts["step"].append((time.perf_counter() - t0) * 1e3)
                    parts["step_cpu"].append((time.process_time() - c0) * 1e3)
                    parts["render"].append(tr)
                    parts["loss"].append(tl1)
                    parts["backward"].append(tb)  # the loss's and the rasterizer's
                    parts["stats"].append(ts)
                    parts["adam"].append(ta)
            med = {k: float(np.median(v)) for k, v in parts.items()}
            px = views[0][1].width * views[0][1].height
            rows.append((px, g.num, med["step"], med["step_cpu"]))
            print(f"| {views[0][1].width}x{views[0][1].height} | {px:,} | {g.num:,} | {med['step']:.1f} | "
                  f"{med['step_cpu']:.1f} | {med['render']:.1f} | {med['loss']:.1f} | {med['backward']:.1f} | {med['stats']:.1f} | "
                  f"{med['adam']:.1f} |", flush=True)
    if len(rows) >= 4:
        A = np.array([[1.0, p, n, p * n] for p, n, _, _ in rows])
        for col, name in ((2, "wall"), (3, "CPU")):
            y = np.array([r[col] for r in rows]) / 1e3
            coef, *_ = np.linalg.lstsq(A, y, rcond=None)
            err = float(np.max(np.abs(A @ coef - y) / y))
            print(f"\nstep {name} seconds ~ {coef[0]:.3g} + {coef[1]:.3g} * pixels + {coef[2]:.3g} * Gaussians + "
                  f"{coef[3]:.3g} * pixels * Gaussians ({args.threads} threads; largest error {100 * err:.0f}%)")


if __name__ == "__main__":
    main()
