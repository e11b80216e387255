"""Stage ``capture``: render the embedded synthetic demo capture, or import the user's photos.

    anigs capture --params '{...synthetic section...}' --out results/demo/capture
    anigs capture --source photos --photos DIR --params '{"max_side": 1600}' --out results/garden/capture

Synthetic mode writes ``OUT/images/*.png`` and the ground truth in ``OUT/gt/``
(see :mod:`anigs.synth.capture`); photos mode writes ``OUT/images/*.png`` only.
"""
from __future__ import annotations

import argparse

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.capture.config import CaptureConfig, capture_config
from anigs.stages.command import parse_params
from anigs.io import write_json
from anigs import contract
from anigs.contract import File
from anigs.photos import import_photos

log = logging.getLogger("anigs.capture")


Config = CaptureConfig  # the `capture` config section


class Outputs(contract.Outputs):
    """The capture stage's folder: the photos, and for the synthetic scene its ground truth
    (:mod:`anigs.synth.capture`)."""

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

    @classmethod
    def from_gt(cls, gt_dir: str | Path) -> "Outputs":
        """The capture folder whose ground-truth folder is ``gt_dir`` (a ``--gt-dir`` argument)."""
        out = cls(Path(gt_dir).parent)
        if out.path("gt") != Path(gt_dir):
            raise ValueError(f"{gt_dir}: not the capture stage's ground-truth folder ({cls.LAYOUT['gt'].name})")
        return out

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
        from anigs.cameras import load_cameras  # torch: kept out of the import (benchmarks/scaling.py)

        return load_cameras(self.path("gt_cameras"))

    def gt_background(self) -> list[float] | None:
        """The RGB background the synthetic photos were rendered on (``gt_cameras``' ``background``)."""
        bg = self.json("gt_cameras").get("background")
        return [float(x) for x in bg] if bg else None

    def gt_gaussians(self):
        """The ground-truth :class:`~anigs.gaussians.Gaussians`."""
        from anigs.gaussians import Gaussians  # torch: kept out of the import (benchmarks/scaling.py)

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


@dataclass
class Inputs(contract.Inputs):
    """What the capture stage reads: nothing upstream; the source and, for photos, their folder."""

    out: Outputs = contract.output_folder(Outputs, "capture folder")
    source: str = field(default="synthetic", metadata={
        "help": "synthetic: render the embedded demo scene; photos: import a folder of photos"})
    photos: Path | None = field(default=None, metadata={"help": "folder of JPEG/PNG photos (photos mode)"})


def run(inputs: Inputs, cfg) -> Outputs:
    """Write ``images/`` (and ``gt/`` for the synthetic scene) and ``capture.json``. ``cfg``: a
    :class:`CaptureConfig` (photos) or the scene's :class:`~anigs.synth.capture.SynthConfig`."""
    out, source, photos = inputs.out, inputs.source, inputs.photos
    if source == "photos":
        if photos is None:
            raise ValueError("--source photos needs --photos DIR (the folder with your photos)")

        names = import_photos(photos, out.path("images"), cfg.max_side or None, cfg.skip_unreadable)
        log.info("imported %d photos from %s into %s", len(names), photos, out.path("images"))
        write_json(out.path("summary"), {"source": "photos", "photos": str(photos), "images": names,
                                         "num_images": len(names)})
        return out
    if source != "synthetic":
        raise ValueError(f"capture: source must be 'synthetic' or 'photos', got {source!r}")
    if photos is not None:
        raise ValueError("--photos is only used with --source photos")

    from anigs.synth.capture import write_capture  # torch: the synthetic scene only

    summary = write_capture(cfg, out)
    write_json(out.path("summary"), {"source": "synthetic", **summary})
    log.info("synthetic capture: %d Gaussians %s, %d images %dx%d in %.1f s -> %s",
             summary["num_gaussians"], summary["label_counts"], summary["num_images"],
             *summary["image_size"], summary["seconds"]["total"], out)
    return out


# ---- command line: anigs capture ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    Inputs.add_arguments(p)
    p.add_argument("--params", default=None,
                   help="JSON (or @file.json/.yaml): the scene's `synthetic` section, or the photo import options")


def main(args: argparse.Namespace) -> int:
    inputs = Inputs.from_args(args)
    run(inputs, capture_config(inputs.source, parse_params(args.params)))
    return 0
