"""The ``export`` config section (:class:`ExportConfig`; the stage: :mod:`anigs.stages.export`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from anigs.typed_config import Section


@dataclass
class ExportConfig(Section):
    """``export`` config section."""

    HANDED = ('fps',)  # set once for the whole run (anigs.config.HANDED), not in this section

    frames: bool = False  # also write the per-frame PLY sequence (scene.anigs holds every frame exactly)
    frame_step: int = 1  # every n-th frame of 0..T-1
    fps: float = 12.0  # frames per second of the written videos / sidecar

    WHERE: ClassVar[str] = "export"
    ERROR: ClassVar[type[Exception]] = KeyError

    def validate(self) -> None:
        if self.frame_step < 1:
            raise ValueError(f"export.frame_step must be >= 1, got {self.frame_step}")
