"""The ``view`` config section (:class:`ViewConfig`): the interactive viewer's page (:mod:`anigs.viewer.build`;
the stage: :mod:`anigs.stages.view`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.typed_config import Section


@dataclass
class ViewConfig(Section):
    """The ``view`` config section."""

    HANDED = ('background', 'fps')  # set once for the whole run (anigs.config.HANDED), not in this section

    background: list = field(default_factory=lambda: [0.5, 0.5, 0.5])  # RGB behind the splats (as final.background)
    fps: float = 12.0  # frames per second of the animation at speed 1x
    embed: bool = True  # also write scene.js, so index.html opens straight from the file system
    title: str = "anigs"  # page title

    WHERE: ClassVar[str] = "view"
    ERROR: ClassVar[type[Exception]] = KeyError
