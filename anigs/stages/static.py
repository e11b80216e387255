"""Stage ``static``: fit the static canonical 3DGS from posed images and SfM points.

    anigs static --images DIR --cameras sfm/cameras.json --points sfm/points.npz \
                 --out results/demo/static [--params JSON]

Writes ``OUT/canonical.ply`` (standard 3DGS layout) and ``OUT/metrics.json``. While it runs,
``OUT/checkpoint.ply`` holds the last good state; it is removed on success and kept when the
fit diverges.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from anigs.static.fit import FitConfig

Config = FitConfig  # the `static` config section

log = logging.getLogger("anigs.static")

def run(images: str | Path, cameras: str | Path, points: str | Path, out: str | Path, cfg: FitConfig,
        progress: bool = False) -> dict:
    """Fit the canonical 3DGS to the posed ``images`` from the SfM ``points``; writes
    ``out/canonical.ply`` and ``out/metrics.json`` and returns the metrics."""
    from anigs.gaussians import load_ply
    from anigs.images import load_inputs
    from anigs.io import write_json
    from anigs.sfm.model import load_points
    from anigs.static.fit import fit_static

    out = Path(out)
    imgs, cams = load_inputs(images, cameras, compact=True)  # uint8: a quarter of the memory
    pts, cols = load_points(points)
    out.mkdir(parents=True, exist_ok=True)
    ckpt = out / "checkpoint.ply"
    gaussians, metrics = fit_static(imgs, cams, pts, cols, cfg, progress=progress, checkpoint_path=ckpt)
    ply = out / "canonical.ply"
    gaussians.save_ply(ply)
    back = load_ply(ply)  # the artifact must round-trip
    if back.num != gaussians.num:
        raise RuntimeError(f"{ply}: wrote {gaussians.num} Gaussians but read back {back.num}")
    metrics["inputs"] = {"images": str(images), "cameras": str(cameras), "points": str(points),
                         "num_points": int(len(pts))}
    metrics["config"] = _config_dict(cfg)
    write_json(out / "metrics.json", metrics)
    if ckpt.exists():
        ckpt.unlink()
    log.info("static fit: %d Gaussians -> %s", metrics["num_gaussians"], ply)
    return metrics


def _config_dict(cfg) -> dict:
    import dataclasses

    d = dataclasses.asdict(cfg)
    d["background"] = list(cfg.background)
    return d


# ---- command line: anigs static ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_out

    p.add_argument("--images", required=True, help="folder of the input images")
    p.add_argument("--cameras", required=True, help="cameras.json (anigs convention), one entry per used image")
    p.add_argument("--points", required=True, help="points.npz with xyz [P,3] and rgb [P,3] (SfM points)")
    add_out(p, "output folder (canonical.ply, metrics.json)")
    add_params(p, "static")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    metrics = run(args.images, args.cameras, args.points, args.out, FitConfig.from_dict(parse_params(args.params)),
                  progress=not args.no_progress)
    print(f"static fit: {metrics['num_gaussians']} Gaussians, held-out PSNR {metrics['test_psnr']:.2f} dB "
          f"(SSIM {metrics['test_ssim']:.3f}), train PSNR {metrics['train_psnr']:.2f} dB, "
          f"{metrics['seconds']:.0f} s -> {Path(args.out) / 'canonical.ply'}")
    return 0
