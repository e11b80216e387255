"""I3D (FVD backbone) cost: seconds per 16-frame clip through anigs' torch I3D at the FVD protocol's input.

    python benchmarks/i3d_cost.py                         # 2 threads, batches of 1 and 4, 3 timed calls
    python benchmarks/i3d_cost.py --threads 1 --repeat 5 --batch 1 4 8

The input is what :func:`anigs.metrics.features.i3d_features` hands the network under the
default protocol: [B,3,16,256,256] in [-1,1] (the 256 centre crop), resized to 224x224 inside
the network (``resize=True``), the packaged Kinetics-400 weights (``eval.i3d_path: auto``).
After one warm-up call per batch size, prints the median wall-clock and process-CPU seconds
per clip, and the load average before and after (the machine may be shared: with a load above
the core count the wall-clock figure is inflated, the CPU-time one less so).
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=2, help="torch threads")
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per batch size")
    ap.add_argument("--batch", type=int, nargs="+", default=[1, 4], help="batch sizes (eval.batch_size is 4)")
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--crop", type=int, default=256, help="the protocol's crop (eval.fvd_crop_size)")
    args = ap.parse_args(argv)

    import torch

    from anigs.metrics.i3d_weights import load_i3d

    torch.set_num_threads(args.threads)
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    net = load_i3d()
    out: dict = {"load_seconds": time.perf_counter() - t0, "threads": args.threads, "per_clip": {}}
    gen = torch.Generator().manual_seed(0)
    for b in args.batch:
        x = torch.rand(b, 3, args.frames, args.crop, args.crop, generator=gen) * 2 - 1
        wall, cpu = [], []
        with torch.no_grad():
            net(x, resize=True, return_features=True)  # warm-up
            for _ in range(args.repeat):
                w0, c0 = time.perf_counter(), time.process_time()
                net(x, resize=True, return_features=True)
                wall.append((time.perf_counter() - w0) / b)
                cpu.append((time.process_time() - c0) / b)
        out["per_clip"][b] = {"wall": statistics.median(wall), "cpu": statistics.median(cpu)}
    out["load_average"] = {"before": load_before, "after": os.getloadavg()}
    print(f"torch {torch.__version__}, {args.threads} threads, {os.cpu_count()} cores; weights loaded in "
          f"{out['load_seconds']:.1f} s")
    for b, r in out["per_clip"].items():
        print(f"batch {b}: {r['wall']:.2f} s wall, {r['cpu']:.2f} s CPU per {args.frames}-frame clip "
              f"({args.crop}x{args.crop} crop -> 224x224), median of {args.repeat}")
    la, lb = out["load_average"]["before"], out["load_average"]["after"]
    print(f"load average (1, 5, 15 min) before {tuple(round(v, 1) for v in la)}, after {tuple(round(v, 1) for v in lb)}")
    return out


if __name__ == "__main__":
    main()
