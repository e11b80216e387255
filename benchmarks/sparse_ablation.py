"""What each weight-free technique for sparse captures buys: the static fit of every capture with each
switch of ``static.sparse``, over several seeds.

    python benchmarks/sparse_ablation.py --cache results/real_captures [--capture NAME ...]
        [--rows base drop pair both warp] [--seeds 0 1 2] [--out results/sparse_ablation] [--threads 2]
        [--static KEY=VALUE ...] [--json OUT]

Reads each capture's sfm folder from ``--cache/<capture>/sfm`` (``benchmarks/real_captures.py`` makes
them), runs ``anigs static`` on it once per row and seed into ``--out/<capture>/<row>-s<seed>`` (a run whose
metrics.json exists is not redone), at the capture's default plan (``static.budget: auto``: 640 px, the
every-8th photo held out) plus the row's switches:

- ``base``: every technique off;
- ``drop``: DropGaussian (``sparse.drop_rate: 0.2``);
- ``pair``: the denser start from photo pairs (``sparse.pair_points: true``);
- ``both``: both;
- ``warp``: the warp loss alone (``sparse.warp_weight: 1``);
- ``stereo``: the dense start from plane-sweep stereo (``sparse.stereo_points: true``);
- ``stereo_drop``: that and DropGaussian.

Prints one row per capture and row: held-out PSNR (the median over the seeds, and max - min), train
PSNR, wall seconds of the fit (median) and the points the start had. The rows are the README's
ablation table ("Sparse walks").
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

ROWS = {
    "base": {"drop_rate": 0.0, "pair_points": False},
    "drop": {"drop_rate": 0.2, "pair_points": False},
    "pair": {"drop_rate": 0.0, "pair_points": True},
    "both": {"drop_rate": 0.2, "pair_points": True},
    "warp": {"warp_weight": 1.0},
    "stereo": {"drop_rate": 0.0, "stereo_points": True},
    "stereo_drop": {"drop_rate": 0.2, "stereo_points": True},
}


def fit(sfm: Path, out: Path, params: dict, threads: int) -> dict:
    """One ``anigs static`` run (skipped when ``out/metrics.json`` exists); returns its metrics plus
    ``wall_s`` (the run's wall seconds, as recorded the first time)."""
    done = out / "metrics.json"
    if not done.exists():
        out.mkdir(parents=True, exist_ok=True)
        exe = Path(sys.executable).with_name("anigs")
        cmd = [str(exe) if exe.exists() else "anigs", "--threads", str(threads), "static", "--images",
               str(sfm / "images"), "--cameras", str(sfm / "cameras.json"), "--points", str(sfm / "points.npz"),
               "--tracks", str(sfm / "tracks.npz"), "--out", str(out), "--params", json.dumps(params),
               "--no-progress"]
        t0 = time.perf_counter()
        with open(out.with_suffix(".log"), "w") as log:
            rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT).returncode
        if rc:
            raise SystemExit(f"{out}: anigs static failed (exit {rc}); see {out.with_suffix('.log')}")
        (out / "wall.json").write_text(json.dumps({"wall_s": time.perf_counter() - t0}))
    m = json.loads(done.read_text())
    m["wall_s"] = json.loads((out / "wall.json").read_text())["wall_s"] if (out / "wall.json").exists() else None
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", type=Path, required=True, help="a real_captures.py cache: CACHE/<capture>/sfm")
    ap.add_argument("--capture", nargs="*", default=None)
    ap.add_argument("--rows", nargs="*", default=list(ROWS), choices=list(ROWS))
    ap.add_argument("--seeds", nargs="*", type=int, default=[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "sparse_ablation")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--static", nargs="*", default=[], help="static KEY=VALUE for every run (dotted keys nest)")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    names = a.capture or sorted(p.parent.name for p in a.cache.glob("*/sfm/cameras.json"))
    from real_captures import nested, parse_kv

    extra = nested(parse_kv(a.static))
    records = []
    print("| capture | row | held-out dB, median (max - min) | train dB | fit s, median | start points "
          "(SfM + pairs) | seeds |")
    print("|---|---|---|---|---|---|---|")
    for capture in names:
        sfm = a.cache / capture / "sfm"
        if not (sfm / "cameras.json").exists():
            raise SystemExit(f"{sfm}: no sfm folder (run benchmarks/real_captures.py --capture {capture} first)")
        for row in a.rows:
            runs = []
            for seed in a.seeds:
                params = {**extra, "seed": seed, "sparse": {**extra.get("sparse", {}), **ROWS[row]}}
                m = fit(sfm, a.out / capture / f"{row}-s{seed}", params, a.threads)
                runs.append(m)
                records.append({"capture": capture, "row": row, "seed": seed, "test_psnr": m["test_psnr"],
                                "train_psnr": m["train_psnr"], "wall_s": m["wall_s"], "seconds": m["seconds"],
                                "num_gaussians": m["num_gaussians"], "init_gaussians": m["init_gaussians"],
                                "pair_points": m.get("pair_points"), "image_size": m["image_size"],
                                "holdout": m["holdout"], "iterations": m["iterations"]})
            te = np.array([r["test_psnr"] for r in runs])
            pts = runs[0]["inputs"]["num_points"], (runs[0].get("pair_points") or {}).get("points", 0)
            print(f"| {capture} | {row} | {np.median(te):.2f} ({np.ptp(te):.2f}) | "
                  f"{np.median([r['train_psnr'] for r in runs]):.2f} | {np.median([r['seconds'] for r in runs]):.0f} | "
                  f"{pts[0]} + {pts[1]} | {len(runs)} |", flush=True)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "2")
    main()
