"""The ``capture`` stage's config: the photo import options (:class:`PhotosConfig`, the ``capture``
section) or, for the synthetic scene, its ``synthetic`` section (:func:`capture_config`)."""
from __future__ import annotations

from dataclasses import dataclass

from anigs.typed_config import from_dict


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


def capture_config(source: str, params: dict | None):
    """The config ``--params`` gives: the photo import options, or the scene's ``synthetic`` section."""
    if source == "photos":
        return PhotosConfig.from_dict(params)
    from anigs.synth.capture import SynthConfig  # torch: the synthetic scene only (photo runs stay light)

    return SynthConfig.from_dict(params)
