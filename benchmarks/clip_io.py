"""Clip file IO: time and size of a clip written deflated (the old format) and stored (now).

    python benchmarks/clip_io.py [CLIP.npz ...] [--repeats 5]

Without arguments a synthetic 25x192x256 clip (smooth image plus render-like noise) is used; pass
real clips (for example a finished run's ``round4/target/*.npz``) for the figures in benchmarks/README.md.
Prints the median write and read time and the size per format, and the ratios.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from anigs.io import write_npz
from anigs.video import load_clip


def _clip() -> np.ndarray:
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:192, 0:256] / 256.0
    base = 0.5 + 0.3 * np.sin(6 * x + 3 * y)[..., None] * np.array([1.0, 0.8, 0.6])
    t = np.arange(25)[:, None, None, None] / 25
    return np.clip(base[None] + 0.05 * np.sin(2 * np.pi * t) + 0.01 * rng.standard_normal((25, 192, 256, 3)), 0, 1)


def _time(fn, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return statistics.median(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    clips = [load_clip(p)[0] for p in a.clips] or [_clip().astype(np.float32)]
    rows = {}
    with tempfile.TemporaryDirectory() as d:
        for compress in (True, False):
            w = r = size = 0.0
            for k, c in enumerate(clips):
                path = Path(d) / f"c{k}_{compress}.npz"
                frames = np.clip(c, 0, 1).astype(np.float16)
                w += _time(lambda: write_npz(path, compress=compress, frames=frames), a.repeats)
                r += _time(lambda: np.load(path)["frames"], a.repeats)
                size += path.stat().st_size
            rows["deflated" if compress else "stored"] = (w / len(clips), r / len(clips), size / len(clips) / 1e6)
    print(f"{len(clips)} clip(s) {clips[0].shape}, median of {a.repeats}")
    print(f"{'format':9s} {'write s':>8s} {'read s':>8s} {'MB':>7s}")
    for k, (w, r, s) in rows.items():
        print(f"{k:9s} {w:8.3f} {r:8.3f} {s:7.2f}")
    (wd, rd, sd), (ws, rs, ss) = rows["deflated"], rows["stored"]
    print(f"stored / deflated: write {ws / wd:.3f}x, read {rs / rd:.3f}x, size {ss / sd:.2f}x")


if __name__ == "__main__":
    main()
