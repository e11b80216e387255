"""Stage ``effects``: which effects the scene contains, and where (its one region of interest).

Analyses the capture photos the SfM cameras describe (the undistorted ``sfm/images``) with the
fitted static model (:func:`anigs.effects.detect_effects`: colour indices, height above the
fitted ground, planarity, texture, multi-view consistency; no downloaded weights, or optionally a
semantic segmenter with local weights: ``effects.segmenter``) and decides,
per effect, whether the scene contains it.

Which of the detected effects the scene simulates (its ``effects:`` list and its prompt) is
:mod:`anigs.effects.choice`. The union of the chosen effects' Gaussians is the region of interest
that the views stage places the views around.

    anigs effects --canonical static/canonical.ply --cameras sfm/cameras.json --images sfm/images \\
        --out effects/ [--static static/] [--requested foliage_sway flower_bob] [--prompt "a garden"] \\
        --params '{...effects section...}'

Writes the files of :class:`Outputs`.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from anigs.effects.choice import decide_effects
from anigs.effects.analysed import photo_indices
from anigs.effects.config import EffectsConfig
from anigs import contract
from anigs.contract import File
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.shared_inputs import CanonicalInputs
from anigs.cameras import load_cameras
from anigs.effects import save_overview
from anigs.gaussians import load_ply
from anigs.images import find_image, load_image
from anigs.io import write_json

Config = EffectsConfig  # the `effects` config section

log = logging.getLogger("anigs.effects")


class Outputs(contract.Outputs):
    """The effects stage's folder: what the scene contains and its region of interest."""

    LAYOUT = {
        "effects": File("effects.json", "per effect: detected, pixel_fraction, gaussian_fraction, confidence, "
                                        "reason; requested, chosen, requested_not_found, prompt, corrections, "
                                        "num_dynamic, dynamic_fraction, config"),
        "regions": File("regions.npy", "int8 [N]: region of each canonical Gaussian (index into "
                                       "anigs.effects.config.REGIONS), -1 none"),
        "dynamic": File("dynamic.npy", "bool [N]: the chosen effects' Gaussians, the region of interest"),
        "overview": File("overview.png", "uint8 RGB: the numbered candidates over the photos"),
    }

    def report(self) -> dict:
        """``effects.json``."""
        return self.json("effects")

    def chosen(self) -> list[str]:
        """The effects the stage chose to simulate (may be empty: nothing moves)."""
        return list(self.report()["chosen"])

    def regions(self, n: int | None = None) -> np.ndarray:
        """int8 [N] region index of each canonical Gaussian (-1 none); ``n``: the canonical model's size."""
        return self.array("regions", "i", (n,))

    def dynamic(self, n: int | None = None) -> np.ndarray:
        """bool [N] the region of interest; ``n``: the canonical model's size."""
        return self.array("dynamic", "b", (n,))


@dataclass
class Inputs(CanonicalInputs):
    """What the effects stage reads: the canonical model and the photos the SfM cameras describe."""

    cameras: Path = contract.upstream(SfmOutputs, "cameras", "cameras of the photos")
    images: Path = contract.upstream(SfmOutputs, "images", "the undistorted photos the cameras describe")
    out: Outputs = contract.output_folder(Outputs)
    requested: list[str] | None = field(default=None, metadata={
        "help": "effects to simulate, instead of the section's `requested` ('auto': the detected kinds the prompt names)"})
    prompt: str | None = field(default=None, metadata={"help": "the scene's prompt, instead of the section's `prompt`"})
    static: StaticOutputs | None = field(default=None, metadata={
        "help": "the static stage's folder: its fit's too-blurry warning goes into effects.json and the overview "
                "(omitted: no warning)"})


def analysed_photos(images: Path, cams: list, cfg: EffectsConfig) -> tuple[list[np.ndarray], list]:
    """(photos, cameras) the detection analyses: the evenly spaced ``effects.photos.max_photos`` of the capture's
    cameras, and only those photos read from the folder ``images``."""
    cams = [cams[i] for i in photo_indices(len(cams), cfg.photos.max_photos)]
    return [load_image(find_image(images, c.name)) for c in cams], cams


def run(inputs: Inputs, cfg: EffectsConfig) -> Outputs:
    """Detect the scene's effects and write the stage's outputs (``inputs.requested`` and
    ``inputs.prompt``, when given, replace the section's)."""
    if inputs.prompt is not None:  # a new section: the caller's stays as it was
        cfg = replace(cfg, prompt=inputs.prompt)
    requested = cfg.requested if inputs.requested is None else inputs.requested  # the section, unless given
    if requested in ([], ["auto"]):
        requested = "auto"
    g = load_ply(inputs.canonical)
    cams = load_cameras(inputs.cameras)
    if not cams:
        raise ValueError(f"{inputs.cameras}: no cameras")
    photos, cams = analysed_photos(Path(inputs.images), cams, cfg)
    decision = decide_effects(photos, cams, g, cfg, requested)
    out = inputs.out
    out.root.mkdir(parents=True, exist_ok=True)
    out.save_array("regions", decision.result.region_of.astype(np.int8))
    out.save_array("dynamic", decision.dynamic)
    warning = inputs.static.fit_warning() if inputs.static is not None else None  # the fit's verdict on its sharpness
    if warning:
        decision.report["static_fit_warning"] = warning
    save_overview(out.path("overview"), decision.result, warnings=[warning] if warning else ())
    write_json(out.path("effects"), decision.report)
    return out
