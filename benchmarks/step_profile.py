"""Where one static-fit step's CPU time goes, part by part, at a given photo size and Gaussian count.

    python benchmarks/step_profile.py --sfm RESULTS/photos/sfm --ply RESULTS/photos/static/canonical.ply
        [--sizes 987x740,640x480] [--gaussians 100000] [--reps 8] [--threads 1]

The step is :func:`anigs.static.fit.train_step`'s (render at SH degree 3 on a random background, L1 +
fused SSIM, backward, densification statistics, fused Adam), on the capture's SfM photos scaled to
each size, with the fitted model grown or thinned to ``--gaussians`` (rows copied with a small jitter,
as ``benchmarks/fit_cost.py``). Each kernel entry point is wrapped with a timer, so the render and the
backward split into: projection (+ SH colour), depth sort and tile counts, rasterizer forward (binning
+ compositing), rasterizer backward, projection backward, SSIM forward/backward kernels, and the torch
glue around them; the loss's torch part, the statistics and Adam are timed around their calls; one
densification (``refine``: clone, split, prune of a model with accumulated statistics) is timed
separately. All figures are process CPU milliseconds (every thread of the process; the machine is
shared, so wall time is not quoted), medians over ``--reps`` steps after two warm-ups. Prints one
Markdown table per size and the (tile, Gaussian) pair count the binning produced.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

KERNEL_PARTS = {  # kernel entry point -> part name
    "anigs_preprocess": "projection",
    "anigs_sort_count": "sort",
    "anigs_composite_forward": "raster fwd",
    "anigs_composite_backward": "raster bwd",
    "anigs_preprocess_backward": "projection bwd",
    "anigs_ssim_forward": "SSIM fwd",
    "anigs_ssim_backward": "SSIM bwd",
}


class Timers:
    """Process-CPU milliseconds accumulated per part name within one step."""

    def __init__(self) -> None:
        self.acc: dict[str, float] = {}
        self.pairs = 0

    def add(self, name: str, ms: float) -> None:
        self.acc[name] = self.acc.get(name, 0.0) + ms

    def wrap(self, lib, fname: str, name: str) -> None:
        fn = getattr(lib, fname)
        if getattr(fn, "_timed", False):
            return

        def timed(*a):
            c0 = time.process_time()
            out = fn(*a)
            self.add(name, (time.process_time() - c0) * 1e3)
            if fname == "anigs_sort_count":
                self.pairs = next(x for x in a if hasattr(x, "_obj"))._obj.value  # the byref(npairs) argument
            return out

        timed._timed = True
        setattr(lib, fname, timed)


def _cpu(fn, timers: Timers, name: str):
    c0 = time.process_time()
    out = fn()
    timers.add(name, (time.process_time() - c0) * 1e3)
    return out


def grow(g, n: int, gen):
    """``g`` with ``n`` rows: copies of its rows jittered by 0.3 x their mean scale (or its first n)."""
    import torch

    if not n or n == g.num:
        return g
    idx = torch.arange(n) % g.num
    jitter = torch.randn(n, 3, generator=gen) * g.log_scales.exp()[idx].mean(1, keepdim=True) * 0.3
    jitter[: min(n, g.num)] = 0
    return type(g)(g.means[idx] + jitter, g.quats[idx], g.log_scales[idx], g.opacity_logits[idx], g.sh[idx])


def main() -> None:
    import numpy as np
    import torch
    import torch.nn.functional as F

    from anigs.gaussians import load_ply
    from anigs.images import load_inputs
    from anigs.render import kernel as render_kernel
    from anigs.ssim import kernel as ssim_kernel
    from anigs.stages.sfm import Outputs as SfmOutputs
    from anigs.static.densify import DensifyConfig, DensifyState, refine, update_state
    from anigs.static.evaluate import render_params, loss_fn
    from anigs.static.init import to_params, make_optimizer

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True)
    ap.add_argument("--ply", required=True)
    ap.add_argument("--sizes", default="987x740,640x480", help="WxH list (the photos are scaled to each)")
    ap.add_argument("--gaussians", default="100000")
    ap.add_argument("--reps", type=int, default=8)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sfm = SfmOutputs(args.sfm)
    imgs, cams = load_inputs(sfm.path("images"), sfm.path("cameras"))
    base = load_ply(args.ply)
    timers = Timers()
    for fname, name in KERNEL_PARTS.items():
        lib = ssim_kernel.load() if "ssim" in fname else render_kernel.load()
        timers.wrap(lib, fname, name)
    order = ["projection", "sort", "raster fwd", "render glue", "loss fwd (torch)", "SSIM fwd", "raster bwd",
             "projection bwd", "SSIM bwd", "backward glue", "densify stats", "Adam"]
    for n_want in [int(x) for x in args.gaussians.split(",")]:
        g = grow(base, n_want, torch.Generator().manual_seed(0))
        for size in args.sizes.split(","):
            w, h = (int(v) for v in size.lower().split("x"))
            params = to_params(g, torch.device("cpu"))
            opt = make_optimizer(params, {k: 1e-4 for k in params})
            views = []
            for im, c in list(zip(imgs, cams))[: args.reps]:
                x = F.interpolate(im.permute(2, 0, 1)[None].float(), size=(h, w), mode="bilinear", antialias=True)
                x = x[0].permute(1, 2, 0).clamp(0, 1)
                cs = c.scaled(w, h)
                views.append((x.contiguous() / (255.0 if im.dtype == torch.uint8 else 1.0), cs,
                              (cs.torch_viewmat(), cs.torch_K())))
            rows: list[dict[str, float]] = []
            pairs = []
            state = DensifyState.empty(g.num)
            bgs = torch.rand(len(views) + 2, 3, generator=torch.Generator().manual_seed(1))
            for rep in range(len(views) + 2):  # two warm-up steps
                target, cam, mats = views[rep % len(views)]
                timers.acc = {}
                c0 = time.process_time()
                rgb, _, meta = _cpu(lambda: render_params(params, cam, 3, bgs[rep], "cpu", mats), timers, "render")
                meta["means2d"].retain_grad()
                loss = _cpu(lambda: loss_fn(rgb, target, 0.2), timers, "loss")
                _cpu(loss.backward, timers, "backward")
                _cpu(lambda: update_state(state, meta, cam.width, cam.height), timers, "densify stats")
                _cpu(lambda: (opt.step(), opt.zero_grad(set_to_none=True)), timers, "Adam")
                a = dict(timers.acc)
                a["step"] = (time.process_time() - c0) * 1e3
                a["render glue"] = a.pop("render") - sum(a.get(k, 0) for k in ("projection", "sort", "raster fwd"))
                a["loss fwd (torch)"] = a.pop("loss") - a.get("SSIM fwd", 0)
                a["backward glue"] = a.pop("backward") - sum(a.get(k, 0) for k in ("raster bwd", "projection bwd",
                                                                                    "SSIM bwd"))
                if rep >= 2:
                    rows.append(a)
                    pairs.append(timers.pairs)
            # one densification from the statistics gathered above
            cfg = DensifyConfig(start=1, stop=2, every=1, max_gaussians=int(g.num * 1.1))
            gen = torch.Generator().manual_seed(0)
            c0 = time.process_time()
            refine(params, opt, state, 1, cfg, 10.0, gen)
            t_refine = (time.process_time() - c0) * 1e3
            med = {k: float(np.median([r.get(k, 0.0) for r in rows])) for k in order + ["step"]}
            print(f"\n{w}x{h}, {g.num:,} Gaussians, {args.threads} thread(s), {int(np.median(pairs)):,} (tile, "
                  f"Gaussian) pairs; process CPU ms, median of {len(rows)} steps:\n")
            print("| part | ms | share |\n|---|---|---|")
            for k in order:
                print(f"| {k} | {med[k]:.1f} | {100 * med[k] / med['step']:.0f}% |")
            print(f"| **step** | **{med['step']:.1f}** | |")
            print(f"| (one densification, every 100 steps) | {t_refine:.1f} | |", flush=True)


if __name__ == "__main__":
    main()
