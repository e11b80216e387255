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

from anigs.typed_config import from_dict
from anigs.cli import parse_params
from anigs.io import write_json

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
