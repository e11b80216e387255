"""The ``refine`` config section (:class:`RefineConfig`): the video prior and the ComposedV2V composition
of a refinement (:func:`anigs.refine.job.refine_clip`; the stage: :mod:`anigs.stages.refine`)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

from anigs.refine.prior.ltx import LTXConfig
from anigs.refine.prior.procedural import ProceduralConfig
from anigs.typed_config import Section


@dataclass
class RefineConfig(Section):
    """The ``refine`` stage's config section."""

    HANDED = ('seed',)  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "refine params"

    prior: str = "procedural"        # procedural (offline, CPU) | ltx (LTX-Video, local weights, GPU)
    strength: float = 0.5            # 0 = keep the clip's motion, 1 = new motion (LTX: starting sigma)
    steps: int = 8                   # LTX Euler steps (procedural: unused)
    compose: bool = True             # False = "w/o ComposedV2V" ablation
    feather_px: float = 0.0          # inward mask feathering for the composition, pixels
    dilate_px: int = 0               # grow the masks by this many pixels (room for silhouettes to move)
    repaste_static: bool = True      # static pixels of frame 0 pasted back after refinement
    prompt: str = ""                 # text prompt (LTX; procedural: keywords pick effects / intensity)
    #: effect types to synthesise (the workflow passes the scene's effects)
    effects: list[str] = field(default_factory=lambda: ["foliage_sway", "leaf_flutter"])
    seed: int = 0                    # global seed (combined with round and view)
    #: the procedural prior (its effects: this section's)
    procedural: ProceduralConfig = field(default_factory=ProceduralConfig)
    ltx: LTXConfig = field(default_factory=LTXConfig)  # the LTX-Video prior (its steps: this section's)

    # Keys of the nested sections that the stage sets from this section's top level (not user keys: one that
    # differs from its default fails).
    DERIVED: ClassVar[dict[str, tuple[str, ...]]] = {"procedural": ("effects",), "ltx": ("steps",)}

    def validate(self) -> None:
        for sub, keys in self.DERIVED.items():
            for key in keys:
                if getattr(getattr(self, sub), key) != getattr(type(getattr(self, sub))(), key):
                    raise ValueError(f"set `{key}` at the top level of the refine params, not in `{sub}`")

    def with_effects(self, chosen: list[str] | None) -> "RefineConfig":
        """With the effects stage's chosen effects instead of the listed ones (``chosen``: None keeps them)."""
        if chosen is not None:
            self.effects = chosen
        return self

    def prior_config(self) -> dict[str, Any]:
        if self.prior == "procedural":
            return {**dataclasses.asdict(self.procedural), "effects": list(self.effects)}
        if self.prior == "ltx":
            return {**dataclasses.asdict(self.ltx), "steps": self.steps}
        raise ValueError(f"unknown video prior {self.prior!r}; available: ['procedural', 'ltx']")
