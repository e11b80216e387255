"""The ``final`` config section (:class:`FinalConfig`): the final videos, the moving-camera video and the
space-time slices (:mod:`anigs.animate.final_videos`; the stage: :mod:`anigs.stages.final`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.typed_config import Section


@dataclass
class FinalConfig(Section):
    """``final`` config section."""

    frames: int = 0  # frames per video (0 = the model's T); fractional times loop the DCT period
    fps: int = 12  # frames per second of the written videos / sidecar
    path_frames: int = 96  # frames of the moving-camera video
    path_loops: int = 2  # how many animation periods the moving camera sees
    path_views: int = 6  # capture cameras the path passes through (evenly picked)
    scale: float = 1.0  # resolution factor of the view videos
    #: RGB in [0,1] behind the splats, where the views show what no photo covered (a neutral grey; a
    #: synthetic scene's own sky: its scene file's `background`)
    background: list = field(default_factory=lambda: [0.5, 0.5, 0.5])
    slice_upsample: int = 4  # each time step becomes this many rows in slice PNGs
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)

    WHERE: ClassVar[str] = "final"
    ERROR: ClassVar[type[Exception]] = KeyError
