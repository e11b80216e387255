"""Stage ``refine``: ComposedV2V refinement of one rendered camera-fixed clip.

    anigs refine --render-clip round1/ --view v003 --masks masks/ [--effects effects/] \\
                 --out round1/ --params '{"prior": "procedural", "strength": 0.5}'

Reads ``round1/render/v003.npz`` and ``masks/v003.png`` and writes ``round1/target/v003.npz``.
``--mask`` gives masks instead (one, all effects inside it, or repeated ``EFFECT=PATH`` per
effect). ``--effects``: synthesise the effects stage's chosen effects instead of the listed
ones. The noise seed combines the config's ``seed``, the round (``--round``, else parsed from the
``round{R}`` folder) and the view, so every view and round draws independent noise.
"""
from __future__ import annotations

import logging
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Mapping

import numpy as np

from anigs.typed_config import from_dict
from anigs.refine.prior.ltx import LTXConfig
from anigs.refine.prior.procedural import ProceduralConfig
from anigs.stages import contract
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.contract import File
from anigs.stages.render_clip import Outputs as RenderClipOutputs

log = logging.getLogger("anigs.refine")


@dataclass
class RefineConfig:
    """The ``refine`` stage's config section."""

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

    # Keys of the nested sections that the stage sets from this section's top level (not user keys).
    DERIVED: ClassVar[dict[str, tuple[str, ...]]] = {"procedural": ("effects",), "ltx": ("steps",)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "RefineConfig":
        for sub, keys in cls.DERIVED.items():
            for key in keys:
                if isinstance(d, Mapping) and key in (d.get(sub) or {}):
                    raise ValueError(f"set `{key}` at the top level of the refine params, not in `{sub}`")
        return from_dict(cls, d, "refine params", ValueError)

    def with_effects(self, effects: EffectsOutputs | None) -> "RefineConfig":
        """With the effects stage's chosen effects instead of the listed ones (``effects``: None keeps them)."""
        if effects is not None:
            self.effects = effects.chosen()
        return self

    def prior_config(self) -> dict[str, Any]:
        if self.prior == "procedural":
            return {**dataclasses.asdict(self.procedural), "effects": list(self.effects)}
        if self.prior == "ltx":
            return {**dataclasses.asdict(self.ltx), "steps": self.steps}
        raise ValueError(f"unknown video prior {self.prior!r}; available: ['procedural', 'ltx']")


Config = RefineConfig  # the `refine` config section


class Outputs(contract.Outputs):
    """A round's folder (``round{r}/``): the refined target clips of its views."""

    STAGE = "refine"
    FOLDER = "{scene}/{variant}/round{round}"
    LAYOUT = {"targets": File("target/", "the round's target clips"),
              "target": File("target/{view}.npz", "refined clip float [T,H,W,3] in [0,1]; metadata: the rendered "
                                                  "clip's + refine (seed, sigmas, view, round)")}

    def target(self, view: str) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of ``view``'s target clip."""
        from anigs.video import load_clip

        p = self.path("target", view=view)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the refine stage)")
        return load_clip(p)


@dataclass
class Inputs(contract.Inputs):
    render_clip: RenderClipOutputs
    view: str = field(metadata={"help": "view id"})
    out: Path = field(metadata={"help": "the round's folder (the target goes to target/{view}.npz)"})
    masks: MasksOutputs | None = None
    mask: list[str] | None = field(default=None, metadata={"help": "[EFFECT=]PATH mask files instead of --masks' "
                                                                   "(several: one per effect)"})
    effects: EffectsOutputs | None = field(default=None, metadata={"help": "the effects stage's folder: synthesise its "
                                                                           "chosen effects"})
    round: int | None = field(default=None, metadata={"help": "round number (default: from the round{R} folder)"})
    info: Path | None = field(default=None, metadata={"help": "JSON file of what was done (sigmas, seed, timing)"})


def listed_effects(synthetic: bool, requested: str | list[str]) -> list[str] | None:
    """The effects to synthesise by name: a synthetic scene's explicitly listed effects are its ground
    truth (whatever the effects stage found); None: the effects stage's choice (``--effects``)."""
    return list(requested) if synthetic and requested != "auto" else None


def run(inputs: Inputs, cfg: RefineConfig, priors: dict | None = None) -> Outputs:
    """Refine ``inputs.view``'s rendered clip into the round's target; ``priors``: as in
    :func:`anigs.refine.job.refine_clip`."""
    from anigs.refine.job import parse_masks, refine_clip

    if inputs.mask:
        masks = parse_masks(inputs.mask)
    elif inputs.masks is not None:
        masks = inputs.masks.view_mask(inputs.view)
    else:
        raise ValueError("refine: give --masks DIR (the masks stage's folder) or --mask PATH")
    out = Outputs(inputs.out)
    info = refine_clip(inputs.render_clip.path("clip", view=inputs.view), masks, out.path("target", view=inputs.view),
                       cfg.with_effects(inputs.effects), inputs.round, inputs.view, priors)
    if inputs.info:
        from anigs.io import write_json

        write_json(inputs.info, info)
    return out
