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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.refine.config import RefineConfig
from anigs import contract
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.contract import File
from anigs.stages.render_clip import Outputs as RenderClipOutputs
from anigs.io import write_json
from anigs.refine.job import parse_masks, refine_clip

log = logging.getLogger("anigs.refine")


Config = RefineConfig  # the `refine` config section


class Outputs(contract.RoundOutputs):
    """A round's folder (``round{r}/``): the refined target clips of its views."""

    LAYOUT = {"targets": File("target/", "the round's target clips"),
              "target": File("target/{view}.npz", "refined clip float [T,H,W,3] in [0,1]; metadata: the rendered "
                                                  "clip's + refine (seed, sigmas, view, round)")}

    def target(self, view: str) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of ``view``'s target clip."""
        return self.clip("target", view=view)


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

    if inputs.mask:
        masks = parse_masks(inputs.mask)
    elif inputs.masks is not None:
        masks = inputs.masks.view_mask(inputs.view)
    else:
        raise ValueError("refine: give --masks DIR (the masks stage's folder) or --mask PATH")
    out = Outputs(inputs.out)
    info = refine_clip(inputs.render_clip.path("clip", view=inputs.view), masks, out.path("target", view=inputs.view),
                       cfg.with_effects(inputs.effects.chosen() if inputs.effects is not None else None), inputs.round,
                       inputs.view, priors)
    if inputs.info:
        write_json(inputs.info, info)
    return out
