"""Blend-weight benchmark: ``anigs.render.visibility.blend_weights`` through one forward + backward
pass of the cpu rasterizer (old) against the forward-only kernel pass (new).

    python benchmarks/blend_weights.py                          # the finished demo run in results/demo
    python benchmarks/blend_weights.py --run /tmp/s2/results/demo --threads 1 --repeat 10

Scene: the run's ``static/canonical.ply``, its ``views/views.json`` cameras and their
``masks/vXX.png`` masks (``>= 0.5``; all-false where a view has none). Per camera the two paths
run interleaved ``--repeat`` times each (after one warm-up call); prints the median wall-clock
and process-CPU ms per call of each, their ratio, and the largest difference of the weights
(total and inside-mask, pixel units) over all cameras. The machine may be shared: the CPU-time
figures are the steadier ones then.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", type=Path, default=ROOT / "results" / "demo", help="a finished run directory")
    ap.add_argument("--threads", type=int, default=1, help="torch (and kernel) threads")
    ap.add_argument("--repeat", type=int, default=5, help="timed calls per camera and path")
    ap.add_argument("--cameras", type=int, default=0, help="use only the first N cameras (0 = all)")
    args = ap.parse_args(argv)

    import numpy as np
    import torch

    sys.path.insert(0, str(ROOT))
    torch.set_num_threads(args.threads)
    from anigs.render.visibility import _blend_backend, blend_weights, blend_weights_backward
    from anigs.stages.masks import Outputs as MasksOutputs
    from anigs.stages.static import Outputs as StaticOutputs
    from anigs.stages.views import Outputs as ViewsOutputs

    if _blend_backend() != "cpu":
        raise SystemExit("the cpu rasterizer kernel is not available: nothing to compare")
    g = StaticOutputs(args.run / "static").canonical()
    cams = ViewsOutputs(args.run / "views").views()
    if args.cameras:
        cams = cams[: args.cameras]
    run_masks = MasksOutputs(args.run / "masks")
    masks = [run_masks.view_mask(cam.name) >= 0.5 if run_masks.has_view_mask(cam.name)
             else np.zeros((cam.height, cam.width), bool) for cam in cams]

    paths = {"old (forward+backward)": blend_weights_backward, "new (forward only)": blend_weights}
    wall = {k: [] for k in paths}
    cpu = {k: [] for k in paths}
    max_diff = max_rel = 0.0
    max_w = 0.0
    for cam, mask in zip(cams, masks):
        res = {k: f(g, cam, mask) for k, f in paths.items()}  # warm-up, and the weights to compare
        (t_old, i_old), (t_new, i_new) = res.values()
        max_diff = max(max_diff, float(np.abs(t_old - t_new).max()), float(np.abs(i_old - i_new).max()))
        max_rel = max(max_rel, float((np.abs(t_old - t_new) / np.maximum(np.abs(t_old), 1e-3)).max()))
        max_w = max(max_w, float(t_old.max()))
        for _ in range(args.repeat):
            for k, f in paths.items():
                w0, c0 = time.perf_counter(), time.process_time()
                f(g, cam, mask)
                wall[k].append(1e3 * (time.perf_counter() - w0))
                cpu[k].append(1e3 * (time.process_time() - c0))

    print(f"scene: {g.num} Gaussians, {len(cams)} cameras {cams[0].width}x{cams[0].height}, "
          f"{args.repeat} calls per camera and path, threads={args.threads}")
    out = {}
    for k in paths:
        out[k] = (statistics.median(wall[k]), statistics.median(cpu[k]))
        print(f"  {k:24s} median {out[k][0]:7.2f} ms wall, {out[k][1]:7.2f} ms CPU per call")
    (ow, oc), (nw, nc) = out.values()
    print(f"  speed-up old/new: {ow / nw:.2f}x wall, {oc / nc:.2f}x CPU")
    print(f"  max |weight difference|: {max_diff:.3g} pixels (largest total weight {max_w:.3g}; "
          f"max relative difference of totals >= 1e-3: {max_rel:.3g})")
    return {"old_ms": ow, "new_ms": nw, "old_cpu_ms": oc, "new_cpu_ms": nc, "max_abs_diff": max_diff}


if __name__ == "__main__":
    main()
