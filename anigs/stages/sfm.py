"""Stage ``sfm``: COLMAP structure from motion on a folder of images.

    anigs sfm --images results/demo/capture/images --out results/demo/sfm \\
        [--gt-cameras results/demo/capture/gt/cameras.json] [--model DIR] --params '{"camera_model": "PINHOLE"}'

Writes ``sparse/0/``, ``images/``, ``cameras.json``, ``points.npz`` and ``report.json`` into ``--out``
(see :mod:`anigs.sfm.colmap`).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from anigs.sfm.config import SfmConfig
from anigs.stages import contract
from anigs.stages.contract import File

Config = SfmConfig  # the `sfm` config section


class Outputs(contract.Outputs):
    """The sfm stage's folder, laid out like a COLMAP project (see :mod:`anigs.sfm.colmap`)."""

    STAGE = "sfm"
    LAYOUT = {
        "images": File("images/", "the images the cameras describe (undistorted, or copies), named as the cameras"),
        "sparse": File("sparse/", "sparse/0/: COLMAP binary model in the output frame (PINHOLE after undistortion)"),
        "cameras": File("cameras.json", "one camera per registered image (anigs convention, name = file name)"),
        "points": File("points.npz", "xyz [P,3] float32, rgb [P,3] float32 in [0,1], error [P] float32 "
                                     "(reprojection px), track_length [P] int32"),
        "report": File("report.json", "registered images, points, mapping, escalation, ground-truth pose errors"),
        "work": File("work/", "COLMAP database and raw models (--keep-work only)", optional=True),
    }

    def cameras(self) -> list:
        """The registered cameras (:class:`~anigs.cameras.Camera`)."""
        from anigs.cameras import load_cameras

        return load_cameras(self.path("cameras"))

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(xyz [P,3] float64, rgb [P,3] float64 in [0,1]) of the SfM points."""
        from anigs.sfm.model import load_points

        return load_points(self.path("points"))

    def report(self) -> dict:
        """``report.json``."""
        return self.json("report")


def run(images: str | Path, out: str | Path, cfg: SfmConfig, gt_cameras: str | Path | None = None,
        model_dir: str | Path | None = None, keep_work: bool = False, threads: int | None = None) -> dict:
    """Structure from motion of the images in ``images`` into ``out``; returns ``report.json``'s content.

    ``threads``: what ``num_threads: -1`` means (``anigs --threads``, set by Snakemake); all available
    CPUs when None."""
    from anigs.sfm.colmap import run_sfm

    return run_sfm(images, out, cfg, gt_cameras=gt_cameras, model_dir=model_dir, keep_work=keep_work,
                   threads=threads, originals=original_photos(images)).report


def original_photos(images: str | Path) -> Path | None:
    """The folder of the user's photos that ``images`` was imported from (``capture.json`` beside
    ``images``, photos source), when it still exists; the sfm escalation tries them at full size."""
    import json

    summary = Path(images).parent / "capture.json"
    try:
        info = json.loads(summary.read_text())
    except (OSError, ValueError):
        return None
    src = info.get("photos") if info.get("source") == "photos" else None
    return Path(src) if src and Path(src).is_dir() else None


# ---- command line: anigs sfm ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_out

    p.add_argument("--images", required=True, help="folder of JPEG/PNG images")
    add_out(p, "output folder")
    p.add_argument("--gt-cameras", default=None,
                   help="ground-truth cameras JSON (synthetic capture): align to them and report pose errors")
    p.add_argument("--model", default=None,
                   help="existing COLMAP sparse model of these images (skips extraction, matching, mapping)")
    add_params(p, "sfm")
    p.add_argument("--keep-work", action="store_true", help="keep the COLMAP database and raw models in OUT/work")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    r = run(args.images, args.out, SfmConfig.from_dict(parse_params(args.params)), gt_cameras=args.gt_cameras,
            model_dir=args.model, keep_work=args.keep_work, threads=getattr(args, "threads", None))
    line = f"registered {r['registered']}/{r['images']} images, {r['num_points']} points"
    if r.get("partial"):
        line += f" (PARTIAL: left out {', '.join(r['unregistered_images'])})"
    if "gt_errors" in r:
        e = r["gt_errors"]
        line += (f"; rotation error mean {e['rotation_error_deg']['mean']:.3f} max "
                 f"{e['rotation_error_deg']['max']:.3f} deg; centre error mean "
                 f"{e['center_error_pct_extent']['mean']:.3f}% max {e['center_error_pct_extent']['max']:.3f}% of extent")
    print(line)
    return 0
