"""The parameters of effect detection (config section ``effects``): one nested section per step.

The steps of :func:`anigs.effects.detect_effects` and their sections: ``photos`` (which photos, how
large), ``cues`` (the model's 3D cues: up, ground, local shape), ``regions`` (the photo regions' colour
and shape thresholds), ``lift`` (photo regions to Gaussians), ``rules`` (the geometry rules, one
section per rule: :mod:`anigs.effects.rules`), ``decide`` (is a region there), then the user's
corrections (``drop``, ``force``, ``boxes``, ``selections``) and the optional ``segmenter``.

Lengths in pixels are fractions of the photo's diagonal (``*_frac``) so they hold at any resolution;
heights are fractions of the cameras' median height above the fitted ground. A key of the flat section
of anigs 0.13 and earlier fails naming its new key (:data:`RENAMED`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from anigs.effects.kinds import EFFECT_REGION, EFFECTS, PLANTS, REGION_EFFECTS, REGIONS
from anigs.effects.rules import RulesConfig
from anigs.effects.rules.base import MIN_ATTACHED, Bands, fixed
from anigs.effects.rules.own_colour import MIN_WHITE_SHARE
from anigs.typed_config import Section

__all__ = ["CuesConfig", "DecideConfig", "EFFECTS", "EFFECT_REGION", "LiftConfig", "PLANTS", "PhotosConfig",
           "EffectsConfig", "REGIONS", "REGION_EFFECTS", "RENAMED", "RegionsConfig", "RulesConfig", "SegmenterConfig"]

SEGMENTER_BACKENDS: tuple[str, ...] = ("none", "segformer")
SEGMENTER_MODES: tuple[str, ...] = ("gate", "replace")


@dataclass
class SegmenterConfig(Section):
    """Optional learned segmentation (config section ``effects.segmenter``; :mod:`anigs.effects.segmenter`)."""

    HANDED = ('device',)  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "effects.segmenter config"

    #: none (the weight-free cues alone: the default) or segformer (a transformers semantic segmenter, e.g. SegFormer
    #: fine-tuned on ADE20K, from the local folder ``weights``)
    backend: str = "none"
    #: local folder of the segmenter (config.json, model.safetensors or pytorch_model.bin, preprocessor_config.json),
    #: fetched once by the user (README: learned segmentation); nothing is downloaded at run time
    weights: str = ""
    #: gate: the weight-free regions keep only pixels the segmenter calls a plant (foliage, grass, flowers) or water
    #: (made things never move); replace: the segmenter's most likely kind is the pixel's region
    mode: str = "gate"
    min_prob: float = 0.5            # a pixel counts as a kind when the segmenter's summed probability reaches this
    #: label name of the model (its config's id2label, matched by name) -> foliage, grass, flowers, water or still;
    #: merged over the built-in names (tree, plant, palm, grass, field, flower, water, sea, river, lake ...)
    classes: dict = field(default_factory=dict)
    device: str = "auto"             # the segmenter's torch device: auto, cpu or cuda[:N]

    def validate(self) -> None:
        if self.backend not in SEGMENTER_BACKENDS:
            raise ValueError(f"effects.segmenter.backend must be one of {list(SEGMENTER_BACKENDS)}, got {self.backend!r}")
        if self.mode not in SEGMENTER_MODES:
            raise ValueError(f"effects.segmenter.mode must be one of {list(SEGMENTER_MODES)}, got {self.mode!r}")
        if not 0 < self.min_prob <= 1:
            raise ValueError(f"effects.segmenter.min_prob must be in (0, 1], got {self.min_prob}")
        bad = {k: v for k, v in dict(self.classes).items() if v not in (*REGIONS, "still")}
        if bad:
            raise ValueError(f"effects.segmenter.classes: {bad} map to no kind; each label name maps to one of "
                             f"{[*REGIONS, 'still']}")


@dataclass
class PhotosConfig(Section):
    """Step ``photos``: which capture photos are analysed, and how large (``effects.photos``)."""

    WHERE = "effects.photos"

    max_photos: int = 24             # photos analysed (evenly spaced over the capture)
    max_side: int = 400              # photos are downscaled to this longest side (px)
    min_alpha: float = 0.5           # pixels where the fitted model is thinner than this are empty (sky)

    def validate(self) -> None:
        if self.max_photos < 1 or self.max_side < 16:
            raise ValueError(f"effects.photos: max_photos ({self.max_photos}) must be >= 1 and max_side "
                             f"({self.max_side}) >= 16")


@dataclass
class CuesConfig(Section):
    """Step ``cues``: the fitted model's 3D cues: up, the ground plane, the local shape (``effects.cues``)."""

    WHERE = "effects.cues"

    #: world up: "z" (the SfM stage writes z-up) or "auto" (estimated from the cameras and points)
    up: str = "z"
    neighbour_radius: float = 0.06   # 3D neighbourhood radius for planarity, x the median photo depth
    neighbours: int = 32             # at most this many neighbours per Gaussian
    wall_max_variation: float = 0.04  # surface variation below this = locally planar (walls, floors, pictures)
    wall_max_upness: float = 0.35    # |normal . up| below this = vertical
    floor_min_upness: float = 0.85   # |normal . up| above this = horizontal
    ground_margin: float = 0.03      # ground layer: surfaces below this x camera height are ground
    #: ... and below this quantile of how deep the photos see under the ground plane, mirrored upwards (the top of the
    #: seen ground)
    ground_seen_quantile: float = 0.9
    ground_min_support: float = 0.03  # the ground plane counts when this fraction of Gaussians lies on it
    ground_max_below: float = 0.1    # ... and at most this fraction lies clearly under it

    def validate(self) -> None:
        if self.up not in ("z", "auto"):
            raise ValueError(f"effects.cues.up must be 'z' or 'auto', got {self.up!r}")
        if not 0 < self.ground_seen_quantile < 1:
            raise ValueError(f"effects.cues.ground_seen_quantile must be in (0, 1), got {self.ground_seen_quantile}")
        for name in ("neighbour_radius", "ground_margin"):
            if getattr(self, name) <= 0:
                raise ValueError(f"effects.cues.{name} must be > 0, got {getattr(self, name)}")


@dataclass
class RegionsConfig(Section):
    """Step ``regions``: the photo regions' colour and shape thresholds (``effects.regions``;
    :mod:`anigs.effects.regions`)."""

    WHERE = "effects.regions"

    #: plants rising above this x camera height are trees and bushes (foliage); lower ones grass or flower beds
    grass_max_height: float = 0.2
    #: ... and so are plant pixels within this (x photo diagonal) of such a part of the same plant (a bush's lowest
    #: leaves)
    foliage_reach_frac: float = 0.03
    green_hue: tuple = (62.0, 170.0)  # hue band of vegetation (degrees)
    green_min_saturation: float = 0.16  # HSV saturation a vegetation pixel needs at least
    min_value: float = 0.03          # darker pixels carry no colour (dark foliage is still found above this)
    #: a vegetation pixel's chroma (brightest minus darkest channel, RGB in [0,1]) at least this: below it the
    #: hue is noise (a dark stone or a shadow with a faint green cast; shaded leaves keep 0.1 and more)
    green_min_chroma: float = 0.04
    flower_min_saturation: float = 0.45  # HSV saturation a blossom pixel needs at least
    flower_min_value: float = 0.4    # brightest channel of a blossom (darker saturated: soil, bark)
    #: blossoms are saturated colours outside this band (red, yellow, blue, violet)
    flower_green_hue: tuple = (68.0, 215.0)
    white_flowers: bool = True       # bright near-white blobs inside vegetation count as blossoms
    flower_radius_frac: float = 0.025  # a blossom lies within this of vegetation
    flower_min_ring: float = 0.25    # share of a blossom's surroundings that must be vegetation
    #: a blossom lies at most this x its depth behind that vegetation (a wall seen past a bush lies farther)
    flower_max_behind: float = 0.1
    flower_bed_frac: float = 0.015   # closing radius joining blossoms (and the stems between them) into beds
    flower_rim_frac: float = 0.008  # blossoms grow this far over their blended, less saturated rim
    #: low plant components (and low plant pixels' surroundings) with blossoms on this share of their area are beds
    flower_bed_share: float = 0.1
    max_rectangularity: float = 0.9  # green components filling >= this of their bounding rectangle are pictures
    water_hue: tuple = (165.0, 265.0)  # bluish / cyan hues of water (sky reflection, depth)
    water_min_saturation: float = 0.2  # HSV saturation a water pixel needs at least
    water_max_texture: float = 0.035  # local luminance std of water (weakly textured)
    water_max_height: float = 0.06   # water lies below this x camera height above the ground plane
    reflect_min_spread: float = 0.25  # colour spread across photos (relative) that marks a reflective surface
    texture_frac: float = 0.012      # window of the local luminance std
    #: components smaller than this share of the photo are dropped (and a photo shows a region from this share on)
    min_component_frac: float = 0.0004

    def validate(self) -> None:
        for name in ("green_hue", "flower_green_hue", "water_hue"):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) != 2 or not 0 <= v[0] < v[1] <= 360:
                raise ValueError(f"effects.regions.{name} must be (low, high) degrees in [0, 360], got {v}")
            setattr(self, name, v)
        if not 0 <= self.green_min_chroma < 1:
            raise ValueError(f"effects.regions.green_min_chroma must be in [0, 1), got {self.green_min_chroma}")
        for name in ("grass_max_height", "water_max_height"):
            if getattr(self, name) <= 0:
                raise ValueError(f"effects.regions.{name} must be > 0, got {getattr(self, name)}")

    def bands(self) -> Bands:
        """The colour bands the rules read on the Gaussians' own colours."""
        return Bands(self.green_hue, self.green_min_saturation, self.flower_green_hue, self.white_flowers)


@dataclass
class LiftConfig(Section):
    """Step ``lift``: the photos' regions voted onto the Gaussians (``effects.lift``)."""

    WHERE = "effects.lift"

    vote_threshold: float = 0.5      # a Gaussian joins the region voted by this share of the photos that see it
    #: ... and only when at least this share of its blending weight over the photos falls on that region's pixels
    #: (its whole footprint, not its centre: a blurred splat reaching from a bush over a gate or a facade stays
    #: still); 0: off
    footprint_share: float = 0.3
    footprint_reach_px: int = 2      # ... counting pixels within this of the region's (a splat's soft edge)
    #: ... and it stays still where, in photo_vetoes of the photos that show it (anigs.effects.lift.PHOTO_MIN_WEIGHT),
    #: less than this share of its weight there falls on the region's pixels: the photos that show it off the plant
    #: have a say, not only the majority (splats on the street's bushes in most photos painted a facade in two or more);
    #: 0: off
    photo_min_share: float = 0.1
    #: ... so many photos must show it off the region (1: any one; 2 forgives one photo whose masks missed the plant)
    photo_vetoes: int = 2
    propagate_k: int = 8             # Gaussians seen by no photo take the majority of their k neighbours

    def validate(self) -> None:
        if not 0 <= self.photo_min_share <= 1 or self.photo_vetoes < 1:
            raise ValueError(f"effects.lift.photo_min_share must be in [0, 1] and effects.lift.photo_vetoes >= 1, got "
                             f"{self.photo_min_share} and {self.photo_vetoes}")
        if not 0 <= self.footprint_share <= 1 or self.footprint_reach_px < 0:
            raise ValueError(f"effects.lift.footprint_share must be in [0, 1] and effects.lift.footprint_reach_px "
                             f">= 0, got {self.footprint_share} and {self.footprint_reach_px}")
        if not 0 < self.vote_threshold <= 1:
            raise ValueError(f"effects.lift.vote_threshold must be in (0, 1], got {self.vote_threshold}")


@dataclass
class DecideConfig(Section):
    """Step ``decide``: is a region there (``effects.decide``)."""

    WHERE = "effects.decide"

    min_pixel_fraction: float = 0.002   # an effect needs this share of the photos' pixels ...
    min_gaussian_fraction: float = 0.001  # ... and of the Gaussians ...
    min_gaussians: int = 20          # ... and at least this many Gaussians ...
    min_photo_fraction: float = 0.1  # ... and a region in this share of the photos (at least 2)


@dataclass
class EffectsConfig(Section):
    """Parameters of :func:`anigs.effects.detect_effects` (config section ``effects``): one nested section
    per step (module docstring), the user's corrections and the scene's choice."""

    WHERE = "effects config"

    #: effects to simulate: auto (the detected kinds the prompt names; every detected one without a prompt) or a list
    #: of effect names, which overrides the prompt; a listed effect the scene lacks is reported and skipped
    requested: list | str = "auto"
    #: the scene's prompt (the workflow passes the scene file's prompt): with requested auto only the kinds it names
    #: are localised (anigs/effects/vocabulary.py); null = no prompt
    prompt: str | None = None
    #: which photos are analysed, and how large
    photos: PhotosConfig = field(default_factory=PhotosConfig)
    #: the fitted model's 3D cues: up, the ground plane, the local shape
    cues: CuesConfig = field(default_factory=CuesConfig)
    #: the photo regions' colour and shape thresholds (anigs/effects/regions.py)
    regions: RegionsConfig = field(default_factory=RegionsConfig)
    #: the photos' regions voted onto the Gaussians
    lift: LiftConfig = field(default_factory=LiftConfig)
    #: the geometry rules, one section per rule (anigs/effects/rules; the table of rules in config/README.md)
    rules: RulesConfig = field(default_factory=RulesConfig)
    #: is a region there: how much of the photos and the Gaussians it needs
    decide: DecideConfig = field(default_factory=DecideConfig)
    # the user's corrections (anigs/effects/corrections.py; numbers as in overview.png)
    drop: list = field(default_factory=list)  # numbered candidates of overview.png that must not move
    force: list = field(default_factory=list)  # numbered candidates a geometry rule set aside that move all the same
    #: 3D boxes {min: [x, y, z], max: [x, y, z], effect: NAME or still, frame: anigs or supersplat}: corners in the
    #: frame of static/canonical.ply (anigs, the default) or as SuperSplat shows positions ((-x, -y, z): supersplat)
    boxes: list = field(default_factory=list)
    #: SuperSplat selection exports {ply: PATH, effect: NAME or still} (PLY or compressed PLY), matched to the fitted
    #: Gaussians by position (moved ones, from animated.ply or a frame, by colour, opacity and scale)
    selections: list = field(default_factory=list)
    #: a selected splat matches the fitted Gaussian within this x the model's bounding-box diagonal
    selection_tol: float = 0.0001
    #: optional learned segmentation of the photos with local weights (default backend none: the weight-free cues)
    segmenter: SegmenterConfig = field(default_factory=SegmenterConfig)


    def validate(self) -> None:
        if isinstance(self.requested, str) and self.requested != "auto":
            raise ValueError(f"effects.requested must be 'auto' or a list of effect names, got {self.requested!r}")
        if not isinstance(self.requested, str):
            unknown = [e for e in self.requested if e not in EFFECTS]
            if unknown:
                raise ValueError(f"effects.requested: unknown effect(s) {unknown}; the valid effects are {list(EFFECTS)}")

    def to_dict(self) -> dict:
        """The section as plain values; ``segmenter`` only when a backend is set (a weight-free run records what
        it recorded before the segmenter existed)."""
        out = _plain(asdict(self))
        if self.segmenter.backend == "none":
            del out["segmenter"]
        return out


def _plain(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return list(x) if isinstance(x, tuple) else x


#: old flat keys whose knob is a constant now (issue 49: it moved no figure)
FIXED: dict[str, str] = {
    "min_attached": fixed("MIN_ATTACHED", MIN_ATTACHED, "anigs/effects/rules/base.py"),
    "flower_own_min_white_share": fixed("MIN_WHITE_SHARE", MIN_WHITE_SHARE, "anigs/effects/rules/own_colour.py"),
}


def _moves() -> dict[str, str]:
    photos = {k: f"photos.{k}" for k in ("max_photos", "max_side", "min_alpha")}
    cues = {k: f"cues.{k}" for k in ("up", "neighbour_radius", "neighbours", "wall_max_variation", "wall_max_upness",
                                      "floor_min_upness", "ground_margin", "ground_seen_quantile", "ground_min_support",
                                      "ground_max_below")}
    regions = {k: f"regions.{k}" for k in (
        "grass_max_height", "foliage_reach_frac", "green_hue", "green_min_saturation", "min_value", "green_min_chroma",
        "flower_min_saturation", "flower_min_value", "flower_green_hue", "white_flowers", "flower_radius_frac",
        "flower_min_ring", "flower_max_behind", "flower_bed_frac", "flower_rim_frac", "flower_bed_share",
        "max_rectangularity", "water_hue", "water_min_saturation", "water_max_texture", "water_max_height",
        "reflect_min_spread", "texture_frac", "min_component_frac")}
    lift = {k: f"lift.{k}" for k in ("vote_threshold", "footprint_share", "footprint_reach_px", "propagate_k")}
    decide = {k: f"decide.{k}" for k in ("min_pixel_fraction", "min_gaussian_fraction", "min_gaussians",
                                         "min_photo_fraction")}
    rules = {"link_frac": "rules.link_frac", "min_candidate": "rules.min_candidate",
             "plane_tol": "rules.plane.tol", "plane_max_share": "rules.plane.max_share",
             "plane_min_extent": "rules.plane.min_extent", "plane_max_outside": "rules.plane.max_outside",
             "plane_smear_min_cos": "rules.smeared_sheet.min_cos",
             "plane_free_outline": "rules.smeared_sheet.free_outline",
             "island_min_share": "rules.islands.min_share", "island_neighbours": "rules.islands.neighbours",
             "min_attached": FIXED["min_attached"],
             "blossoms_with_plants": "rules.blossoms.with_plants",
             "leaf_hue_margin": "rules.sunlit_leaves.hue_margin",
             "crown_min_height": "rules.sunlit_leaves.crown_min_height",
             "flower_own_min_share": "rules.own_colour.min_share",
             "flower_own_min_saturation": "rules.own_colour.min_saturation",
             "flower_own_min_value": "rules.own_colour.min_value",
             "flower_own_min_white_share": FIXED["flower_own_min_white_share"]}
    return {**photos, **cues, **regions, **lift, **decide, **rules}


#: a key of the flat ``effects`` section (anigs 0.13 and earlier) -> its key now
RENAMED: dict[str, str] = {old: new if new in FIXED.values() else f"effects.{new}" for old, new in _moves().items()}
EffectsConfig.RENAMED = RENAMED
