"""Rasterizer benchmark: forward and forward+backward time, throughput, peak memory.

    python benchmarks/raster.py                # small (10k, 256x192) and large (100k, 512x384)
    python benchmarks/raster.py --repeat 20 --threads 2

Scenes (fixed by issue 2): seed 0, N Gaussians in a 2x2x2 cube centred 4 units in front
of the camera, scales log-uniform in [0.01, 0.05], opacities uniform in [0.1, 0.9], SH
degree 0, 60 degree horizontal FOV. Each (scene, backend) runs in its own subprocess so
the reported peak RSS is that run's alone. Prints wall-clock medians (what a user waits)
and process CPU-time medians (robust when the machine is shared), and the load average
before and after (timings from a busy machine are not comparable with quiet ones).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"small": (10_000, 256, 192), "large": (100_000, 512, 384)}
TORCH_MEM_LIMIT_GB = 8.0  # the dense torch reference is skipped above this estimate


def _worker(scene: str, backend: str, repeat: int, threads: int) -> dict:
    import torch

    sys.path.insert(0, str(ROOT))
    torch.set_num_threads(threads)
    from anigs.render import rasterize
    from anigs.render.projection import project_gaussians
    from tests._scenes import random_scene

    n, W, H = SCENES[scene]
    sc = random_scene(n, W, H, 0, seed=0)
    viewmat, K = sc[5].float(), sc[6].float()
    with torch.no_grad():
        p = project_gaussians(*sc[:4], viewmat, K, W, H)
        area = ((p.rects[:, 2] - p.rects[:, 0]) * (p.rects[:, 3] - p.rects[:, 1])).long()
        pairs = int(area.sum())
        if backend == "torch":
            # per-pixel candidate lists are padded to the longest one: estimate before running
            est = W * H * 4.0 * 10 * float(area.sum()) / max(W * H, 1) * 4 / 1e9
            if est > TORCH_MEM_LIMIT_GB:
                return {"scene": scene, "backend": backend, "skipped": f"estimated {est:.0f} GB > {TORCH_MEM_LIMIT_GB} GB"}
    leaves = [t.clone().requires_grad_(True) for t in sc[:5]]

    def fwd():
        with torch.no_grad():
            rasterize(*sc[:5], viewmat, K, W, H, backend=backend)

    def fwd_bwd():
        rgb, alpha, meta = rasterize(*leaves, viewmat, K, W, H, backend=backend)
        (rgb.sum() + alpha.sum()).backward()

    def timed(fn):
        fn()  # warm-up (and kernel load)
        wall, cpu = [], []
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        return statistics.median(wall) * 1e3, statistics.median(cpu) * 1e3

    fw, fc = timed(fwd)
    bw, bc = timed(fwd_bwd)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"scene": scene, "backend": backend, "n": n, "size": f"{W}x{H}", "threads": threads,
            "fwd_ms": fw, "fwd_bwd_ms": bw, "fwd_cpu_ms": fc, "fwd_bwd_cpu_ms": bc,
            "pairs": pairs, "pairs_per_s": pairs / (fw / 1e3), "peak_rss_mb": peak_mb}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenes", default="small,large")
    ap.add_argument("--backends", default="cpu,torch")
    ap.add_argument("--worker", nargs=2, metavar=("SCENE", "BACKEND"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(_worker(*args.worker, args.repeat, args.threads)))
        return
    backends = args.backends.split(",")
    try:
        import torch

        if torch.cuda.is_available() and "gsplat" not in backends:
            backends.append("gsplat")
    except ImportError:
        pass
    load_before = os.getloadavg()
    rows = []
    for scene in args.scenes.split(","):
        for backend in backends:
            rep = args.repeat if backend != "torch" else max(2, args.repeat // 5)
            res = subprocess.run([sys.executable, __file__, "--worker", scene, backend, "--repeat", str(rep),
                                  "--threads", str(args.threads)], capture_output=True, text=True)
            if res.returncode != 0:
                rows.append({"scene": scene, "backend": backend, "skipped": res.stderr.strip().splitlines()[-1]})
            else:
                rows.append(json.loads(res.stdout.strip().splitlines()[-1]))
    load_after = os.getloadavg()
    print(f"threads={args.threads}  (wall = median wall-clock, cpu = median process CPU time)  "
          f"load average (1/5/15 min) before {'/'.join(f'{x:.2f}' for x in load_before)}, "
          f"after {'/'.join(f'{x:.2f}' for x in load_after)}")
    print(f"{'scene':6} {'backend':7} {'fwd ms':>9} {'fwd+bwd ms':>11} {'fwd cpu':>9} {'f+b cpu':>9} "
          f"{'Mpairs/s':>9} {'peak MB':>8}")
    for r in rows:
        if "skipped" in r:
            print(f"{r['scene']:6} {r['backend']:7} skipped: {r['skipped']}")
            continue
        print(f"{r['scene']:6} {r['backend']:7} {r['fwd_ms']:9.1f} {r['fwd_bwd_ms']:11.1f} {r['fwd_cpu_ms']:9.1f} "
              f"{r['fwd_bwd_cpu_ms']:9.1f} {r['pairs_per_s'] / 1e6:9.1f} {r['peak_rss_mb']:8.0f}")
    by = {(r["scene"], r["backend"]): r for r in rows if "skipped" not in r}
    for scene in args.scenes.split(","):
        c, t = by.get((scene, "cpu")), by.get((scene, "torch"))
        if c and t:
            print(f"{scene}: cpu/torch speed-up forward {t['fwd_ms'] / c['fwd_ms']:.1f}x, "
                  f"forward+backward {t['fwd_bwd_ms'] / c['fwd_bwd_ms']:.1f}x "
                  f"(CPU time: {t['fwd_bwd_cpu_ms'] / c['fwd_bwd_cpu_ms']:.1f}x)")


if __name__ == "__main__":
    main()
