"""Model-update benchmark: steps per second and peak memory at demo scale, and how the cost
grows with the number of DCT bases K, the number of dynamic Gaussians D, and the resolution.

    python benchmarks/update.py                 # full table (about 10 minutes on 2 shared cores)
    python benchmarks/update.py --quick         # base configuration only
    python benchmarks/update.py --threads 1 --steps 20

Scene (seed 0): N Gaussians uniform in a 4 x 4 x 1.5 box on the ground (scales log-uniform in
[0.02, 0.05], opacity 0.6, random colours); the dynamic set is a random fraction of them.
V cameras on a ring (radius 5, height 2, 60 degree FOV) look at the centre. Targets are the
canonical renders repeated over T frames (the cost does not depend on their content).
One step = ``views_per_step`` (2) renders at random t + 1 canonical-loss render at t = 0, with
backward and an Adam step (paper default parameter group, deformation+positions).
Each configuration runs in its own subprocess so the peak RSS is that run's alone; the peak
includes the target clips held in memory (V * T * H * W * 3 float32), listed separately.
Prints wall-clock (what a user waits) and process CPU time (robust when the machine is shared).
"""
from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASE = {"n": 30_000, "dyn_frac": 0.3, "T": 25, "views": 8, "width": 256, "height": 192, "K": 16}


def _scene(n: int, dyn_frac: float, seed: int = 0):
    import torch

    from anigs.gaussians import Gaussians

    g = torch.Generator().manual_seed(seed)
    pts = torch.rand(n, 3, generator=g) * torch.tensor([4.0, 4.0, 1.5]) - torch.tensor([2.0, 2.0, 0.0])
    cols = torch.rand(n, 3, generator=g)
    scales = torch.exp(torch.empty(n).uniform_(math.log(0.02), math.log(0.05), generator=g))
    G = Gaussians.from_points(pts, cols, scales, opacity=0.6)
    mask = torch.rand(n, generator=g) < dyn_frac
    return G, mask


def _cameras(v: int, w: int, h: int):
    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    out = []
    for k in range(v):
        a = 2 * math.pi * k / v
        out.append(Camera(intrinsics_from_fov(60, w, h), look_at((5 * math.cos(a), 5 * math.sin(a), 2.0), (0, 0, 0.5)),
                          w, h, f"v{k}"))
    return out


def _worker(cfg: dict, steps: int, threads: int) -> dict:
    import torch

    sys.path.insert(0, str(ROOT))
    torch.set_num_threads(threads)
    from anigs.animate.frames import render_frame
    from anigs.animate.update import ViewData, run_update
    from anigs.animate.config import UpdateConfig

    G, mask = _scene(cfg["n"], cfg["dyn_frac"])
    cams = _cameras(cfg["views"], cfg["width"], cfg["height"])
    with torch.no_grad():
        views = [ViewData(c, render_frame(G, None, c, 0)[None].repeat(cfg["T"], 1, 1, 1)) for c in cams]
    ucfg = dict(num_bases=cfg["K"], views_per_step=2, cano_views_per_step=1, lambda_cano=0.1, seed=0)
    run_update(G, mask, views, UpdateConfig(steps=1, **ucfg), progress=False)  # warm-up (kernel load)
    c0 = time.process_time()
    res = run_update(G, mask, views, UpdateConfig(steps=steps, **ucfg), progress=False)
    cpu = time.process_time() - c0
    clips_mb = cfg["views"] * cfg["T"] * cfg["height"] * cfg["width"] * 3 * 4 / 2**20
    return {**cfg, "D": int(mask.sum()), "steps": steps, "threads": threads,
            "wall_steps_per_s": steps / res.seconds, "cpu_s_per_step": cpu / steps,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "clips_mb": clips_mb}


def _run(cfg: dict, steps: int, threads: int) -> dict:
    cmd = [sys.executable, __file__, "--worker", json.dumps(cfg), "--steps", str(steps), "--threads", str(threads)]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        return {**cfg, "error": out.stderr.strip().splitlines()[-1] if out.stderr else "failed"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=15)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="base configuration only")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(_worker(json.loads(args.worker), args.steps, args.threads)))
        return
    rows = [("base", BASE)]
    if not args.quick:
        rows += [(f"K={k}", {**BASE, "K": k}) for k in (4, 24)]
        rows += [(f"dyn={f:.0%}", {**BASE, "dyn_frac": f}) for f in (0.1, 1.0)]
        rows += [(f"{w}x{h}", {**BASE, "width": w, "height": h}) for w, h in ((128, 96), (512, 384))]
        rows += [("N=50k,T=49,V=12", {**BASE, "n": 50_000, "T": 49, "views": 12})]
    print(f"model update benchmark: {args.steps} steps per configuration, {args.threads} torch/OpenMP threads; "
          "one step = 2 renders at random t + 1 canonical render, backward, Adam")
    hdr = f"{'config':<16}{'N':>7}{'D':>7}{'K':>4}{'T':>4}{'V':>4}{'size':>9}{'steps/s':>9}{'cpu s/step':>11}" \
          f"{'peak MB':>9}{'clips MB':>9}"
    print(hdr)
    print("-" * len(hdr))
    for name, cfg in rows:
        r = _run(cfg, args.steps, args.threads)
        if "error" in r:
            print(f"{name:<16} error: {r['error']}")
            continue
        print(f"{name:<16}{r['n']:>7}{r['D']:>7}{r['K']:>4}{r['T']:>4}{r['views']:>4}"
              f"{str(r['width']) + 'x' + str(r['height']):>9}{r['wall_steps_per_s']:>9.2f}{r['cpu_s_per_step']:>11.3f}"
              f"{r['peak_rss_mb']:>9.0f}{r['clips_mb']:>9.0f}", flush=True)


if __name__ == "__main__":
    main()
