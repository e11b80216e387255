"""Stage ``capture``: render the embedded synthetic demo capture, or import the user's photos.

    anigs capture --params '{...synthetic section...}' --out results/demo/capture
    anigs capture --source photos --photos DIR --params '{"max_side": 1600}' --out results/garden/capture

Synthetic mode writes ``OUT/images/*.png`` and the ground truth in ``OUT/gt/``
(see :mod:`anigs.synth.capture`); photos mode writes ``OUT/images/*.png`` only.
"""
from __future__ import annotations

import argparse

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anigs.configs import from_dict
from anigs.cli import parse_params
from anigs.io import write_json
from anigs.stages import contract
from anigs.stages.contract import File

log = logging.getLogger("anigs.capture")


@dataclass
class PhotosConfig:
    """Photo import parameters (``--params`` in photos mode)."""

    max_side: int = 1600  # downscale so the longest side is at most this (0 = keep the original size)
    skip_unreadable: bool = False  # leave out corrupt, unreadable or blank photos with a warning instead of failing

    def __post_init__(self) -> None:
        if self.max_side < 0:
            raise ValueError(f"photos.max_side must be >= 0 (0 = keep size), got {self.max_side}")

    @staticmethod
    def from_dict(d: dict | None) -> "PhotosConfig":
        return from_dict(PhotosConfig, d, "photos", check_types=True)


Config = PhotosConfig  # the `capture` config section


class Outputs(contract.Outputs):
    """The capture stage's folder: the photos, and for the synthetic scene its ground truth
    (:mod:`anigs.synth.capture`)."""

    STAGE = "capture"
    LAYOUT = {
        "images": File("images/", "the photos (PNG; synthetic: img_000.png, ...; photos: {stem}.png)"),
        "summary": File("capture.json", "source (synthetic|photos), image names and count; synthetic: "
                                        "Gaussian and label counts, image size, seconds"),
        "gt": File("gt/", "synthetic only: the ground truth", optional=True),
        "gt_cameras": File("gt/cameras.json", "ground-truth cameras (+ background, time)", optional=True),
        "gt_gaussians": File("gt/gaussians.ply", "ground-truth Gaussians (standard 3DGS layout, SH 0)", optional=True),
        "gt_labels": File("gt/labels.npy", "int32 [N]: semantic label per ground-truth Gaussian", optional=True),
        "gt_anchors": File("gt/anchors.npy", "float32 [N,3]: sway anchor per ground-truth Gaussian", optional=True),
        "gt_motion": File("gt/motion.json", "motion parameters + label/effect tables", optional=True),
        "gt_scene": File("gt/scene.json", "the full synthetic config, label counts, timing", optional=True),
    }

    def summary(self) -> dict:
        """``capture.json``."""
        return self.json("summary")

    def original_photos(self) -> Path | None:
        """The folder of the user's photos the images were imported from (photos source), when it
        still exists; None otherwise (synthetic, or no summary)."""
        try:
            info = self.summary()
        except (OSError, ValueError):
            return None
        src = info.get("photos") if info.get("source") == "photos" else None
        return Path(src) if src and Path(src).is_dir() else None

    def is_synthetic(self) -> bool:
        """Whether the folder holds the synthetic ground truth (``gt/``)."""
        return self.path("gt").is_dir()

    def gt_cameras(self) -> list:
        """The ground-truth cameras (:class:`~anigs.cameras.Camera`)."""
        from anigs.cameras import load_cameras

        return load_cameras(self.path("gt_cameras"))

    def gt_gaussians(self):
        """The ground-truth :class:`~anigs.gaussians.Gaussians`."""
        from anigs.gaussians import Gaussians

        return Gaussians.load_ply(self.path("gt_gaussians"))

    def gt_labels(self, n: int | None = None) -> np.ndarray:
        """int [N] semantic label per ground-truth Gaussian."""
        return self.array("gt_labels", "iu", (n,))

    def gt_anchors(self, n: int | None = None) -> np.ndarray:
        """float32 [N,3] sway anchor per ground-truth Gaussian."""
        return self.array("gt_anchors", "f", (n, 3))

    def gt_motion(self) -> dict:
        """``gt/motion.json``: motion parameters and the label/effect tables."""
        return self.json("gt_motion")


def run(out: str | Path, source: str = "synthetic", params: dict | None = None,
        photos: str | Path | None = None) -> dict:
    """Write ``out/images`` (and ``out/gt`` for the synthetic scene) and ``out/capture.json``; returns
    the summary. ``params``: the scene's ``synthetic`` section, or the ``capture`` section for photos."""
    out = Path(out)
    if source == "photos":
        if photos is None:
            raise ValueError("--source photos needs --photos DIR (the folder with your photos)")
        cfg = PhotosConfig.from_dict(params)
        from anigs.photos import import_photos

        names = import_photos(photos, out / "images", cfg.max_side or None, cfg.skip_unreadable)
        log.info("imported %d photos from %s into %s", len(names), photos, out / "images")
        summary = {"source": "photos", "photos": str(photos), "images": names, "num_images": len(names)}
        write_json(out / "capture.json", summary)
        return summary
    if source != "synthetic":
        raise ValueError(f"capture: source must be 'synthetic' or 'photos', got {source!r}")
    if photos is not None:
        raise ValueError("--photos is only used with --source photos")
    from anigs.synth.capture import SynthConfig, write_capture

    summary = write_capture(SynthConfig.from_dict(params), out)
    write_json(out / "capture.json", {"source": "synthetic", **summary})
    log.info("synthetic capture: %d Gaussians %s, %d images %dx%d in %.1f s -> %s",
             summary["num_gaussians"], summary["label_counts"], summary["num_images"],
             *summary["image_size"], summary["seconds"]["total"], out)
    return {"source": "synthetic", **summary}


# ---- command line: anigs capture ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--source", choices=("synthetic", "photos"), default="synthetic",
                   help="synthetic: render the embedded demo scene; photos: import a folder of photos")
    p.add_argument("--params", default=None,
                   help="JSON (or @file.json/.yaml): the scene's `synthetic` section, or the photo import options")
    p.add_argument("--photos", type=Path, default=None, help="folder of JPEG/PNG photos (photos mode)")
    p.add_argument("--out", type=Path, required=True, help="capture folder: writes OUT/images (and OUT/gt)")


def main(args: argparse.Namespace) -> int:
    run(args.out, args.source, parse_params(args.params), args.photos)
    return 0
