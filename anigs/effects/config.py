"""Regions, the effects each region carries, and the parameters of effect detection.

A *region* is what the detector finds (foliage, grass, flowers, water); an *effect* is what the
animation simulates. Foliage carries two effects (``foliage_sway``, ``leaf_flutter``) that share
its masks and Gaussians.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

from anigs.typed_config import from_dict

REGIONS: tuple[str, ...] = ("foliage", "grass", "flowers", "water")
REGION_EFFECTS: dict[str, tuple[str, ...]] = {
    "foliage": ("foliage_sway", "leaf_flutter"),
    "grass": ("grass_wave",),
    "flowers": ("flower_bob",),
    "water": ("water_ripple",),
}
EFFECT_REGION: dict[str, str] = {e: r for r, effs in REGION_EFFECTS.items() for e in effs}
EFFECTS: tuple[str, ...] = tuple(EFFECT_REGION)
SEGMENTER_BACKENDS: tuple[str, ...] = ("none", "segformer")
SEGMENTER_MODES: tuple[str, ...] = ("gate", "replace")


@dataclass
class SegmenterConfig:
    """Optional learned segmentation (config section ``effects.segmenter``; :mod:`anigs.effects.segmenter`)."""

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

    def __post_init__(self) -> None:
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

    @staticmethod
    def from_dict(d: dict | None) -> "SegmenterConfig":
        """Build from ``effects.segmenter``; unknown keys are an error naming them."""
        return from_dict(SegmenterConfig, d, "effects.segmenter config", ValueError)


@dataclass
class Config:
    """Parameters of :func:`anigs.effects.detect_effects` (config section ``effects``).

    Lengths in pixels are fractions of the photo's diagonal (``*_frac``) so they hold at any
    resolution; heights are fractions of the cameras' median height above the fitted ground.
    """

    #: effects to simulate: auto (the detected kinds the prompt names; every detected one without a prompt) or a list
    #: of effect names, which overrides the prompt; a listed effect the scene lacks is reported and skipped
    requested: list | str = "auto"
    #: the scene's prompt (the workflow passes the scene file's prompt): with requested auto only the kinds it names
    #: are localised (anigs/effects/vocabulary.py); null = no prompt
    prompt: str | None = None
    # photos
    max_photos: int = 24             # photos analysed (evenly spaced over the capture)
    max_side: int = 400              # photos are downscaled to this longest side (px)
    min_alpha: float = 0.5           # pixels where the fitted model is thinner than this are empty (sky)
    # geometry
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
    #: plants rising above this x camera height are trees and bushes (foliage); lower ones grass or flower beds
    grass_max_height: float = 0.2
    #: ... and so are plant pixels within this (x photo diagonal) of such a part of the same plant (a bush's lowest
    #: leaves)
    foliage_reach_frac: float = 0.03
    # colour
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
    #: a flower candidate: this share of its Gaussians' own colours (or more) are a blossom's ...
    flower_own_min_share: float = 0.15
    flower_own_min_saturation: float = 0.3  # ... at least this saturation ...
    flower_own_min_value: float = 0.45  # ... and this brightest channel (bark and soil are darker)
    flower_own_min_white_share: float = 0.35  # ... or this share are white (not greenish: glare on leaves)
    flower_radius_frac: float = 0.025  # a blossom lies within this of vegetation
    flower_min_ring: float = 0.25    # share of a blossom's surroundings that must be vegetation
    #: a blossom lies at most this x its depth behind that vegetation (a wall seen past a bush lies farther)
    flower_max_behind: float = 0.1
    flower_bed_frac: float = 0.015   # closing radius joining blossoms (and the stems between them) into beds
    flower_rim_frac: float = 0.008  # blossoms grow this far over their blended, less saturated rim
    #: low plant components (and low plant pixels' surroundings) with blossoms on this share of their area are beds
    flower_bed_share: float = 0.1
    max_rectangularity: float = 0.9  # green components filling >= this of their bounding rectangle are pictures
    # water
    water_hue: tuple = (165.0, 265.0)  # bluish / cyan hues of water (sky reflection, depth)
    water_min_saturation: float = 0.2  # HSV saturation a water pixel needs at least
    water_max_texture: float = 0.035  # local luminance std of water (weakly textured)
    water_max_height: float = 0.06   # water lies below this x camera height above the ground plane
    reflect_min_spread: float = 0.25  # colour spread across photos (relative) that marks a reflective surface
    texture_frac: float = 0.012      # window of the local luminance std
    # geometry rules (anigs/effects/rules.py): what cannot move
    link_frac: float = 1.0           # a region's Gaussians within this x neighbour radius form one numbered candidate
    min_candidate: int = 10          # parts with fewer Gaussians are checked by the rules but not numbered
    plane_tol: float = 0.25          # a Gaussian within this x neighbour radius of a plane lies on it
    #: foliage / flowers with this share on a large plane lie on a wall, floor, facade, picture, rug or lawn: still
    plane_max_share: float = 0.6
    plane_min_extent: float = 2.0    # ... on up to 3 planes each spanning at least this x neighbour radius
    #: ... each a surface: its band from 1 to 2 plane_tol off holds at most this x its Gaussians (a slice through
    #: flower heads holds more)
    plane_max_outside: float = 0.2
    #: ... unless (foliage) the sheet is a crown the fit smeared in depth (anigs/effects/outline.py): its longest axis
    #: runs along the rays of the photos that show it (median |cos| at least plane_smear_min_cos; walls, pictures,
    #: rugs and lawns spread across the view) and at least plane_free_outline of its outline ring in those photos
    #: sees the sky or something deeper (paint and pictures lie flush); plane_free_outline > 1: off
    plane_smear_min_cos: float = 0.8
    plane_free_outline: float = 0.15  # ... and this share of its outline sees the sky or deeper (> 1: off)
    #: a plant Gaussian (foliage, grass, flowers) with fewer than this share of its island_neighbours nearest Gaussians
    #: in plant regions does not move: green on a surface that is not a plant (moss on a stone, paint); 0: off (the
    #: default: on the real-capture benchmark 0.35 stills less of the marked stones and gate but moves less of the plants)
    island_min_share: float = 0.0
    island_neighbours: int = 16      # ... among this many nearest Gaussians
    #: flowers: this share of a candidate must lie within the link of leaves or stems (held by a plant)
    min_attached: float = 0.3
    #: a prompt that names plants (foliage) but no flowers: the blossoms the flower rules keep and that the named
    #: plants hold (min_attached of them within the link of foliage) sway with them as foliage (a flowering shrub's
    #: blossoms); false: blossoms stay still unless the prompt names flowers
    blossoms_with_plants: bool = True
    #: flowers: a median hue this many degrees below the green band, high in a crown, is sunlit leaves (foliage)
    leaf_hue_margin: float = 20.0
    #: ... high in a crown: most of it above this x camera height (flower heads stay lower)
    crown_min_height: float = 0.4
    # regions and decisions
    min_component_frac: float = 0.0004  # components smaller than this share of the photo are dropped
    min_pixel_fraction: float = 0.002   # an effect needs this share of the photos' pixels ...
    min_gaussian_fraction: float = 0.001  # ... and of the Gaussians ...
    min_gaussians: int = 20          # ... and at least this many Gaussians ...
    min_photo_fraction: float = 0.1  # ... and a region in this share of the photos (at least 2)
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
    vote_threshold: float = 0.5      # a Gaussian joins the region voted by this share of the photos that see it
    #: ... and only when at least this share of its blending weight over the photos falls on that region's pixels
    #: (its whole footprint, not its centre: a blurred splat reaching from a bush over a gate or a facade stays
    #: still); 0: off
    footprint_share: float = 0.3
    footprint_reach_px: int = 2      # ... counting pixels within this of the region's (a splat's soft edge)
    propagate_k: int = 8             # Gaussians seen by no photo take the majority of their k neighbours
    #: optional learned segmentation of the photos with local weights (default backend none: the weight-free cues)
    segmenter: SegmenterConfig = field(default_factory=SegmenterConfig)

    def __post_init__(self) -> None:
        if isinstance(self.requested, str) and self.requested != "auto":
            raise ValueError(f"effects.requested must be 'auto' or a list of effect names, got {self.requested!r}")
        if not isinstance(self.requested, str):
            unknown = [e for e in self.requested if e not in EFFECTS]
            if unknown:
                raise ValueError(f"effects.requested: unknown effect(s) {unknown}; the valid effects are {list(EFFECTS)}")
        if self.up not in ("z", "auto"):
            raise ValueError(f"effects.up must be 'z' or 'auto', got {self.up!r}")
        if self.max_photos < 1 or self.max_side < 16:
            raise ValueError(f"effects: max_photos ({self.max_photos}) must be >= 1 and max_side "
                             f"({self.max_side}) >= 16")
        for name in ("green_hue", "flower_green_hue", "water_hue"):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) != 2 or not 0 <= v[0] < v[1] <= 360:
                raise ValueError(f"effects.{name} must be (low, high) degrees in [0, 360], got {v}")
            setattr(self, name, v)
        if not 0 < self.ground_seen_quantile < 1:
            raise ValueError(f"effects.ground_seen_quantile must be in (0, 1), got {self.ground_seen_quantile}")
        if not 0 <= self.island_min_share <= 1 or self.island_neighbours < 1:
            raise ValueError(f"effects.island_min_share must be in [0, 1] (got {self.island_min_share}) and "
                             f"island_neighbours >= 1 (got {self.island_neighbours})")
        if not 0 <= self.footprint_share <= 1 or not 0 <= self.green_min_chroma < 1 or self.footprint_reach_px < 0:
            raise ValueError(f"effects.footprint_share must be in [0, 1], effects.green_min_chroma in [0, 1) and "
                             f"effects.footprint_reach_px >= 0, got {self.footprint_share}, {self.green_min_chroma} "
                             f"and {self.footprint_reach_px}")
        if not 0 < self.vote_threshold <= 1:
            raise ValueError(f"effects.vote_threshold must be in (0, 1], got {self.vote_threshold}")
        for name in ("neighbour_radius", "grass_max_height", "water_max_height", "ground_margin"):
            if getattr(self, name) <= 0:
                raise ValueError(f"effects.{name} must be > 0, got {getattr(self, name)}")

    @staticmethod
    def from_dict(d: dict | None) -> "Config":
        """Build from a config section; unknown keys are an error naming them."""
        return from_dict(Config, d, "effects config", ValueError)

    def to_dict(self) -> dict:
        """The section as plain values; ``segmenter`` only when a backend is set (a weight-free run records what
        it recorded before the segmenter existed)."""
        out = asdict(self)
        if self.segmenter.backend == "none":
            del out["segmenter"]
        return {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}
