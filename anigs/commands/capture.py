"""``anigs capture``: render the embedded synthetic demo capture, or import the user's photos.

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

from anigs.cli import parse_params
from anigs.io import write_json
from anigs.synth.scene import dataclass_from_dict

log = logging.getLogger("anigs.capture")


@dataclass
class PhotosConfig:
    """Photo import parameters (``--params`` in photos mode)."""

    max_side: int = 1600  # downscale so the longest side is at most this (0 = keep the original size)
    skip_unreadable: bool = False  # skip corrupt/unreadable files with a warning instead of failing

    def __post_init__(self) -> None:
        if self.max_side < 0:
            raise ValueError(f"photos.max_side must be >= 0 (0 = keep size), got {self.max_side}")

    @staticmethod
    def from_dict(d: dict | None) -> "PhotosConfig":
        return dataclass_from_dict(PhotosConfig, d, "photos")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--source", choices=("synthetic", "photos"), default="synthetic",
                   help="synthetic: render the embedded demo scene; photos: import a folder of photos")
    p.add_argument("--params", default=None,
                   help="JSON (or @file.json/.yaml): the scene's `synthetic` section, or the photo import options")
    p.add_argument("--photos", type=Path, default=None, help="folder of JPEG/PNG photos (photos mode)")
    p.add_argument("--out", type=Path, required=True, help="capture folder: writes OUT/images (and OUT/gt)")


def run(args: argparse.Namespace) -> int:
    params = parse_params(args.params)
    if args.source == "photos":
        if args.photos is None:
            raise ValueError("--source photos needs --photos DIR (the folder with your photos)")
        cfg = PhotosConfig.from_dict(params)
        from anigs.photos import import_photos

        names = import_photos(args.photos, args.out / "images", cfg.max_side or None, cfg.skip_unreadable)
        log.info("imported %d photos from %s into %s", len(names), args.photos, args.out / "images")
        write_json(args.out / "capture.json", {"source": "photos", "photos": str(args.photos), "images": names,
                                               "num_images": len(names)})
        return 0
    if args.photos is not None:
        raise ValueError("--photos is only used with --source photos")
    from anigs.synth.capture import SynthConfig, write_capture

    cfg = SynthConfig.from_dict(params)
    summary = write_capture(cfg, args.out)
    write_json(args.out / "capture.json", {"source": "synthetic", **summary})
    log.info("synthetic capture: %d Gaussians %s, %d images %dx%d in %.1f s -> %s",
             summary["num_gaussians"], summary["label_counts"], summary["num_images"],
             *summary["image_size"], summary["seconds"]["total"], args.out)
    return 0
