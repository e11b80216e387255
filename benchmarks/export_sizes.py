"""Size of the animated exports per second of animation and per moving Gaussian.

    python benchmarks/export_sizes.py RESULTS/SCENE/VARIANT [--static RESULTS/SCENE/static] [--sog-frames N]

Reads ``export/animated.json`` (T frames at fps, D moving Gaussians) and prints one Markdown row per
format: ``scene.anigs``, ``animated.ply``, the PLY frame sequence (T files; every frame PLY has the
same size, so it is T x the size of one written frame), the compressed-PLY sequence and the SOG
sequence through splat-transform (``.node/``, ``envs/npm.sh``; SOG with ``-g cpu -i 1``). SOG costs
about 100 CPU seconds per 30k-splat frame on this machine, so ``--sog-frames N`` (default 1) encodes
N frames and scales their mean size to T frames (the table says so). The frames are rebuilt from
``animated.ply`` (:func:`anigs.export.load_animated_ply`). One second of animation is T / fps
(one pass of the frames; the ping-pong loop plays 2 (T - 1) frames). "Motion bytes per moving
Gaussian" is (size - the size of one static frame of that format) / D.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = ROOT / ".node" / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs"


def _convert(src: Path, dst: Path, *extra: str) -> int:
    subprocess.run(["node", str(CLI), "-q", "-w", *extra, str(src), str(dst)], check=True, capture_output=True)
    return dst.stat().st_size


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variant", type=Path, help="RESULTS/SCENE/VARIANT (holds export/)")
    ap.add_argument("--sog-frames", type=int, default=1, help="frames to encode as SOG (0: none)")
    ap.add_argument("--name", default=None, help="the scene's name in the table")
    a = ap.parse_args()

    import torch

    from anigs.animate.frames import deformed
    from anigs.export import load_animated_ply

    exp = a.variant / "export"
    meta = json.loads((exp / "animated.json").read_text())
    T, fps, D = meta["num_frames"], meta["fps"], meta["num_dynamic"]
    seconds = T / fps
    canonical, deformation = load_animated_ply(exp / "animated.ply", T)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        frames = []
        with torch.no_grad():
            for t in range(T):
                deformed(canonical, deformation, t).detach().save_ply(tmp / f"frame_{t:04d}.ply")
                frames.append(tmp / f"frame_{t:04d}.ply")
        one_ply = frames[0].stat().st_size
        canonical.save_ply(tmp / "static.ply")
        rows.append(("scene.anigs", (exp / "scene.anigs").stat().st_size, one_ply, "exact frames"))
        limited = any(meta.get("limits", {}).values())
        rows.append(("animated.ply", (exp / "animated.ply").stat().st_size, one_ply,
                     "soft limits baked out: approximate" if limited else "exact (no soft limits)"))
        rows.append((f"PLY frames ({T})", sum(f.stat().st_size for f in frames), one_ply, "float32"))
        if CLI.is_file():
            comp = [_convert(f, f.with_suffix(".compressed.ply")) for f in frames]
            static_c = _convert(tmp / "static.ply", tmp / "static.compressed.ply")
            rows.append((f"compressed PLY frames ({T})", sum(comp), static_c, "splat-transform 3.7.0 (8-11 bit steps per 256 splats)"))
            if a.sog_frames:
                n = min(a.sog_frames, T)
                sog = [_convert(f, f.with_suffix(".sog"), "-g", "cpu", "-i", "1") for f in frames[:n]]
                mean = sum(sog) / n
                rows.append((f"SOG frames ({T}; {n} encoded, x{T / n:g})", mean * T, mean,
                             "splat-transform 3.7.0, -g cpu -i 1"))
    name = a.name or a.variant.parent.name
    print(f"{name}: T = {T} frames at {fps:g} fps = {seconds:.2f} s, N = {canonical.num} Gaussians, D = {D} moving, "
          f"SH degree {canonical.sh_degree}")
    print("| scene | format | MB | MB per second | motion bytes per moving Gaussian | note |")
    print("|---|---|---|---|---|---|")
    for fmt, size, static, note in rows:
        motion = (size - static) / D if D else float("nan")
        print(f"| {name} | {fmt} | {size / 1e6:.2f} | {size / 1e6 / seconds:.2f} | {motion:,.0f} | {note} |")


if __name__ == "__main__":
    main()
