"""Stage ``masks``: dynamic-region mask per queued view, and the dynamic Gaussian set.

Each view of ``views.json`` is segmented in its first frame (rendered from the canonical model, or
``--frames DIR``: ``{id}.png`` or frame 0 of ``{id}.npz``) by ``masks.backend``: ``effects``
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
from anigs.io import atomic_path, read_json, write_json
from anigs.masks import compute_masks
from anigs.pixels import overlay
from anigs.images import write_mask_png, write_rgb_png
from anigs.masks.choose import EffectSets
from anigs.masks.frames import first_frames
from anigs.masks.labels import LabelsConfig
from anigs.masks.lift import LiftConfig
from anigs.masks.sam2 import Sam2Config
from anigs.masks.vegetation import VegetationConfig
from anigs.masks.segment import segment_views
from anigs.masks.truth import GroundTruth, compare
from anigs.stages import contract
from anigs.stages.contract import File
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.views import cameras_from_views

log = logging.getLogger("anigs.masks")


class Outputs(contract.Outputs):
    """The masks stage's folder: a dynamic mask per queued view and the dynamic Gaussian set."""

    STAGE = "masks"
    FOLDER = "{scene}/masks"
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
        from anigs.images import read_mask

        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE} stage)")
        return contract.check_array(read_mask(p), str(p), "f", (None, None))

    def dynamic(self, n: int | None = None) -> np.ndarray:
        """bool [N]: the canonical Gaussians that move; ``n``: the canonical model's size."""
        return self.array("dynamic", "b", (n,))

    def effect_labels(self, n: int | None = None) -> np.ndarray:
        """int8 [N]: 0 static, 1 + region index for each dynamic Gaussian; ``n``: the canonical size."""
        return self.array("effect_labels", "i", (n,))


@dataclass
class MasksConfig:
    """Config section ``masks``."""

    backend: str = "effects"                   # effects (the effects stage's regions) | vegetation | labels | sam2
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # render background (RGB)
    vegetation: VegetationConfig = field(default_factory=VegetationConfig)  # the vegetation backend
    labels: LabelsConfig = field(default_factory=LabelsConfig)  # the labels backend (and the effects backend's renders)
    sam2: Sam2Config = field(default_factory=Sam2Config)        # the SAM2 backend
    lift: LiftConfig = field(default_factory=LiftConfig)        # lifting the 2D masks to the Gaussians
    per_effect: bool = True                    # write one mask per effect type when there are several
    compare: bool = True                       # with --labels: IoU / precision / recall vs ground truth
    #: with --labels, --gt-*, --cameras: also vs appearance labels (a diagnostic: 0.25 s per photo, 12 s of the demo's
    #: 24 s masks job; benchmarks/masks.py reports it too)
    appearance: bool = False
    capture_ground_layer: float = 0.5          # with --images: vegetation ground_layer on the capture photos
    complete_masks: bool = True                # add the pixels the lifted dynamic Gaussians dominate to each mask
    #: move only the Gaussians whose footprint stays inside every view's dilated mask; halos and floaters stay still
    #: (anigs.masks.contain)
    contain: bool = True
    #: containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_margin_px: int = 3
    #: containment: most blending weight (in pixels) a moving Gaussian may put outside the dilated mask of any view
    contain_max_outside_px: float = 0.05

    @staticmethod
    def from_dict(d: dict | None) -> "MasksConfig":
        from anigs.typed_config import from_dict

        cfg = from_dict(MasksConfig, d, "masks config")
        if cfg.backend not in ("effects", "vegetation", "labels", "sam2"):
            raise ValueError(f"masks.backend must be effects, vegetation, labels or sam2, got {cfg.backend!r}")
        if len(cfg.background) != 3:
            raise ValueError(f"masks.background must be [r, g, b], got {cfg.background}")
        if cfg.capture_ground_layer < 0:
            raise ValueError(f"masks.capture_ground_layer must be >= 0, got {cfg.capture_ground_layer}")
        if cfg.contain_margin_px < 0 or not cfg.contain_max_outside_px >= 0:
            raise ValueError("masks.contain_margin_px and masks.contain_max_outside_px must be >= 0, got "
                             f"{cfg.contain_margin_px} and {cfg.contain_max_outside_px}")
        return cfg


Config = MasksConfig  # the `masks` config section


@dataclass
class Inputs(contract.Inputs):
    """What the masks stage reads (see the module docstring for each)."""

    canonical: Path = field(metadata={"help": "canonical 3DGS PLY (static/canonical.ply)"})
    views: Path = field(metadata={"help": "views.json of the views stage"})
    out: Outputs = field(metadata={"help": "output folder"})
    frames: Path | None = field(default=None, metadata={
        "help": "folder with the first frames ({id}.png or {id}.npz clips); default: render the canonical model"})
    labels: Path | None = field(default=None, metadata={
        "help": "per-Gaussian labels .npy: labels backend and/or ground-truth comparison"})
    motion: Path | None = field(default=None, metadata={"help": "motion.json: which labels move, per effect type (with --labels)"})
    gt_gaussians: Path | None = field(default=None, metadata={"help": "PLY the labels belong to when it is not the canonical set"})
    gt_cameras: Path | None = field(default=None, metadata={
        "help": "cameras in the frame of --gt-gaussians (matched by name to --cameras)"})
    cameras: Path | None = field(default=None, metadata={
        "help": "the reconstruction's cameras (sfm/cameras.json), to align with --gt-cameras and to place the --images"})
    images: Path | None = field(default=None, metadata={
        "help": "the capture photos (sfm/images, named after the --cameras): segmented too, and the lifting votes "
                "over them and the queued views"})
    effects: EffectsOutputs | None = field(default=None, metadata={
        "help": "the effects stage's folder: the effects backend renders its chosen effects' Gaussian sets"})


def run(inputs: Inputs, cfg: MasksConfig) -> Outputs:
    """Write the masks of every queued view, the dynamic set, the effect labels and ``masks.json``."""
    g = load_ply(inputs.canonical)
    data = read_json(inputs.views)
    cams = cameras_from_views(data)
    if not cams:
        raise ValueError(f"{inputs.views} lists no views")
    truth = GroundTruth(inputs.labels, inputs.motion, inputs.gt_gaussians, inputs.gt_cameras) if inputs.labels else None
    if truth is not None:
        truth.effects()  # --labels needs --motion: fail before any work
    effects = None
    if inputs.effects is not None:
        e = inputs.effects
        effects = EffectSets(e.chosen(), e.regions(g.num).astype(np.int64), e.dynamic(g.num))
    frames = first_frames(inputs.frames, g, cams, cfg.background)
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
        label_masks = res.masks if cfg.backend == "labels" else compute_masks(truth.backend(g, capture_cams, dataclasses.asdict(cfg.labels)), frames)
        appearance = None
        if cfg.appearance and inputs.gt_gaussians and inputs.gt_cameras and capture_cams is not None:
            appearance = truth.appearance(g, capture_cams, frames, dataclasses.asdict(cfg.labels))
        compare(info, g, frames, res.masks, res.dynamic, truth, label_masks, appearance,
                capture_cams if capture_cams is not None else cams)
    _save_npy(out.path("dynamic"), res.dynamic)
    if res.effect_labels is not None:
        _save_npy(out.path("effect_labels"), res.effect_labels)
    info["config"] = dataclasses.asdict(cfg)
    write_json(out.path("report"), info)
    log.info("masks: wrote %d masks, dynamic.npy (%d of %d Gaussians) to %s", len(frames), int(res.dynamic.sum()),
             g.num, out)
    return out


def _save_npy(path: Path, a: np.ndarray) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.save(fh, a)
