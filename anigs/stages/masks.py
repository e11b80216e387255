"""Stage ``masks``: dynamic-region mask per queued view, and the dynamic Gaussian set.

Each view of ``views.json`` is segmented in its first frame (rendered from the canonical model, or
``--first-frames DIR``: ``{id}.png`` or frame 0 of ``{id}.npz``) by ``masks.backend``: ``effects``
(default: the effects stage's chosen effects rendered), ``vegetation``, ``labels`` or ``sam2``.
The method (the dynamic set lifted from the masks, voting over the capture photos of
``--images``/``--cameras`` too; completion; containment; effect labels) is
:func:`anigs.masks.segment.segment_views`. With ``--labels`` and ``--motion`` (synthetic scenes)
the masks and the set are compared with the ground truth (:mod:`anigs.masks.truth`; with
``--gt-gaussians``, ``--gt-cameras``, ``--cameras`` and ``appearance`` also with the appearance
labels). What it writes: :class:`Outputs`.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.cameras import load_cameras
from anigs.gaussians import load_ply
from anigs.io import write_json
from anigs.pixels import overlay
from anigs.images import write_mask_png, write_rgb_png
from anigs.masks.choose import EffectSets
from anigs.masks.first_frames import first_frames
from anigs.masks.config import MasksConfig
from anigs.masks.segment import segment_views
from anigs.masks.truth import GroundTruth
from anigs.masks.truth_check import compare_with_truth
from anigs import contract
from anigs.contract import File
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.shared_inputs import GroundTruthInputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.views import cameras_from_views
from anigs.images import read_mask

log = logging.getLogger("anigs.masks")


class Outputs(contract.Outputs):
    """The masks stage's folder: a dynamic mask per queued view and the dynamic Gaussian set."""

    LAYOUT = {
        "mask": File("{view}.png", "uint8 [H, W] 0/255: the view's dynamic mask (its first frame)"),
        "effect_mask": File("{view}_{effect}.png", "uint8 [H, W] 0/255: the part of the mask one effect "
                                                   "moves (when the backend gives several effects)", optional=True),
        "overlay": File("{view}_overlay.png", "uint8 RGB [H, W, 3]: the mask over the first frame"),
        "dynamic": File("dynamic.npy", "bool [N]: the canonical Gaussians that move"),
        "effect_labels": File("effect_labels.npy", "int8 [N]: which effect each dynamic Gaussian belongs to "
                                                   "(0 static, 1 + region index; anigs.effects.labels); "
                                                   "with the effects stage's folder", optional=True),
        "report": File("masks.json", "per-view fractions, the lifting, completion and containment; with "
                                     "ground truth the IoU and precision/recall against it; the config"),
    }

    def report(self) -> dict:
        """``masks.json``."""
        return self.json("report")

    def has_view_mask(self, view: str) -> bool:
        return self.exists("mask", view=view)

    def view_mask(self, view: str) -> np.ndarray:
        """float32 [H, W] in [0, 1]: the dynamic mask of ``view`` (0/1 as written)."""
        return self._read_mask(self.path("mask", view=view))

    def effect_masks(self, view: str) -> dict[str, np.ndarray]:
        """effect -> float32 [H, W] in [0, 1]: the per-effect masks of ``view`` (none: a single effect,
        or ``per_effect: false``)."""
        prefix = self.path("effect_mask", view=view, effect="").name[: -len(".png")]
        overlay = self.path("overlay", view=view)
        found = sorted(p for p in self.root.glob(f"{prefix}*.png") if p != overlay)
        return {p.stem[len(prefix):]: self._read_mask(p) for p in found}

    def _read_mask(self, p: Path) -> np.ndarray:
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE} stage)")
        return contract.check_array(read_mask(p), str(p), "f", (None, None))

    def dynamic(self, n: int | None = None) -> np.ndarray:
        """bool [N]: the canonical Gaussians that move; ``n``: the canonical model's size."""
        return self.array("dynamic", "b", (n,))

    def effect_labels(self, n: int | None = None) -> np.ndarray:
        """int8 [N]: 0 static, 1 + region index for each dynamic Gaussian; ``n``: the canonical size."""
        return self.array("effect_labels", "i", (n,))


Config = MasksConfig  # the `masks` config section


@dataclass
class Inputs(GroundTruthInputs):
    """What the masks stage reads (see the module docstring for each)."""

    views: ViewsOutputs = field(metadata={"help": "the views stage's folder (its queue, views.json)"})
    out: Outputs = contract.output_folder(Outputs)
    first_frames: Path | None = field(default=None, metadata={
        "help": "folder with the first frames ({id}.png or {id}.npz clips); default: render the canonical model"})
    cameras: Path | None = contract.upstream(SfmOutputs, "cameras", "the reconstruction's cameras, to align with "
                                             "--gt-cameras and to place the --images", default=None)
    images: Path | None = contract.upstream(SfmOutputs, "images", "the capture photos, named after the --cameras: "
                                            "segmented too, and the lifting votes over them and the queued views",
                                            default=None)
    effects: EffectsOutputs | None = field(default=None, metadata={
        "help": "the effects stage's folder: the effects backend renders its chosen effects' Gaussian sets"})


def run(inputs: Inputs, cfg: MasksConfig) -> Outputs:
    """Write the masks of every queued view, the dynamic set, the effect labels and ``masks.json``."""
    g = load_ply(inputs.canonical)
    data = inputs.views.report()
    cams = cameras_from_views(data)
    if not cams:
        raise ValueError(f"{inputs.views.path('views')} lists no views")
    truth = GroundTruth(inputs.labels, inputs.motion, inputs.gt_gaussians, inputs.gt_cameras) if inputs.labels else None
    if truth is not None:
        truth.effects()  # --labels needs --motion: fail before any work
    effects = None
    if inputs.effects is not None:
        e = inputs.effects
        effects = EffectSets(e.chosen(), e.regions(g.num).astype(np.int64), e.dynamic(g.num))
    frames = first_frames(inputs.first_frames, g, cams, cfg.background)
    capture_cams = load_cameras(inputs.cameras) if inputs.cameras else None
    res = segment_views(cfg, g, frames, np.asarray(data.get("up", [0.0, 0.0, 1.0]), float), effects,
                        f"effects:{inputs.effects.root}" if effects is not None else "", truth, capture_cams,
                        inputs.images)
    out, info = inputs.out, res.info
    for fr, masks in zip(frames, res.masks):
        m = masks["dynamic"]
        write_mask_png(out.path("mask", view=fr.name), m)
        per_effect = {e: v for e, v in masks.items() if e != "dynamic"}
        if cfg.per_effect and len(per_effect) > 1:
            for e, v in per_effect.items():
                write_mask_png(out.path("effect_mask", view=fr.name, effect=e), v)
        write_rgb_png(out.path("overlay", view=fr.name), overlay(fr.image, m))
        info["views"].append({"id": fr.name, "fraction": float(m.mean()),
                              "effects": {e: float(v.mean()) for e, v in per_effect.items()}})
        log.info("masks: %s dynamic %.1f%%", fr.name, 100 * m.mean())
    if truth is not None and cfg.compare:
        compare_with_truth(info, cfg, g, frames, res, truth, capture_cams if capture_cams is not None else cams,
                           capture_cams)
    out.save_array("dynamic", res.dynamic)
    if res.effect_labels is not None:
        out.save_array("effect_labels", res.effect_labels)
    info["config"] = dataclasses.asdict(cfg)
    write_json(out.path("report"), info)
    log.info("masks: wrote %d masks, %s (%d of %d Gaussians) to %s", len(frames), out.path("dynamic").name,
             int(res.dynamic.sum()), g.num, out)
    return out
