"""The ``capture`` stage's config: the photo import options (:class:`CaptureConfig`, the ``capture``
section) or, for the synthetic scene, its ``synthetic`` section (:func:`capture_config`)."""
from __future__ import annotations

from dataclasses import dataclass

from anigs.typed_config import Section


@dataclass
class CaptureConfig(Section):
    """Photo import parameters (the ``capture`` section; ``--params`` in photos mode)."""

    WHERE = "photos"
    CHECK_TYPES = True

    max_side: int = 1600  # downscale so the longest side is at most this (0 = keep the original size)
    skip_unreadable: bool = False  # leave out corrupt, unreadable or blank photos with a warning instead of failing

    def validate(self) -> None:
        if self.max_side < 0:
            raise ValueError(f"photos.max_side must be >= 0 (0 = keep size), got {self.max_side}")


def capture_config(source: str, params: dict | None):
    """The config ``--params`` gives: the photo import options, or the scene's ``synthetic`` section."""
    if source == "photos":
        return CaptureConfig.from_dict(params)
    from anigs.synth.capture import SynthConfig  # torch: the synthetic scene only (photo runs stay light)

    return SynthConfig.from_dict(params)
