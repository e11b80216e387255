"""Stage ``sfm``: COLMAP structure from motion on a folder of images.

    anigs sfm --images results/demo/capture/images --out results/demo/sfm \\
        [--gt-cameras results/demo/capture/gt/cameras.json] [--model DIR] --params '{"camera_model": "PINHOLE"}'

Writes ``sparse/0/``, ``images/``, ``cameras.json``, ``points.npz``, ``tracks.npz`` and ``report.json`` into ``--out``
(see :mod:`anigs.sfm.colmap`).
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.sfm.config import SfmConfig
from anigs import contract
from anigs.stages.command import parse_params
from anigs.contract import File

Config = SfmConfig  # the `sfm` config section


class Outputs(contract.Outputs):
    """The sfm stage's folder, laid out like a COLMAP project (see :mod:`anigs.sfm.colmap`)."""

    LAYOUT = {
        "images": File("images/", "the images the cameras describe (undistorted, or copies), named as the cameras"),
        "sparse": File("sparse/", "sparse/0/: COLMAP binary model in the output frame (PINHOLE after undistortion)"),
        "cameras": File("cameras.json", "one camera per registered image (anigs convention, name = file name)"),
        "points": File("points.npz", "xyz [P,3] float32, rgb [P,3] float32 in [0,1], error [P] float32 "
                                     "(reprojection px), track_length [P] int32"),
        "tracks": File("tracks.npz", "per registered image, the SfM points it observes: rows (x, y, depth) in its "
                                     "pixels and the output frame (anigs.sfm.tracks)"),
        "report": File("report.json", "registered images, points, mapping, escalation, ground-truth pose errors"),
        "work": File("work/", "COLMAP database and raw models (--keep-work only)", optional=True),
    }

    def cameras(self) -> list:
        """The registered cameras (:class:`~anigs.cameras.Camera`)."""
        from anigs.cameras import load_cameras  # lazy, like the two below: `anigs sfm` starts without torch

        return load_cameras(self.path("cameras"))

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(xyz [P,3] float64, rgb [P,3] float64 in [0,1]) of the SfM points."""
        from anigs.sfm.model import load_points

        return load_points(self.path("points"))

    def report(self) -> dict:
        """``report.json``."""
        return self.json("report")


@dataclass
class Inputs(contract.Inputs):
    """What the sfm stage reads: a folder of images (the capture's), optionally ground-truth
    cameras or an existing COLMAP model."""

    images: Path = field(metadata={"help": "folder of JPEG/PNG images (the capture stage's images/)"})
    out: Outputs = field(metadata={"help": "output folder"})
    gt_cameras: Path | None = field(default=None, metadata={
        "help": "ground-truth cameras JSON (synthetic capture): align to them and report pose errors"})
    model: Path | None = field(default=None, metadata={
        "help": "existing COLMAP sparse model of these images (skips extraction, matching, mapping)"})
    keep_work: bool = field(default=False, metadata={"help": "keep the COLMAP database and raw models in OUT/work"})


def run(inputs: Inputs, cfg: SfmConfig, threads: int | None = None) -> Outputs:
    """Structure from motion of ``inputs.images`` into ``inputs.out``.

    ``threads``: what ``num_threads: -1`` means (``anigs --threads``, set by Snakemake); all available
    CPUs when None. The sfm escalation tries the user's original photos at full size when the
    images were imported by the capture stage (its ``capture.json`` beside ``images``)."""
    from anigs.sfm.colmap import run_sfm
    from anigs.stages.capture import Outputs as CaptureOutputs

    originals = CaptureOutputs(Path(inputs.images).parent).original_photos()
    run_sfm(inputs.images, inputs.out, cfg, gt_cameras=inputs.gt_cameras, model_dir=inputs.model,
            keep_work=inputs.keep_work, threads=threads, originals=originals)
    return inputs.out


# ---- command line: anigs sfm ----

def main(args: argparse.Namespace) -> int:
    out = run(Inputs.from_args(args), SfmConfig.from_dict(parse_params(args.params)), threads=getattr(args, "threads", None))
    r = out.report()
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
