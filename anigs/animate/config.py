"""The config sections of the animation stages, one class each: ``animate`` (:class:`AnimateConfig`:
how the dataset-model loop unrolls into rounds, :mod:`anigs.animate.plan`), ``render_clip``
(:class:`RenderClipConfig`), ``update`` (:class:`UpdateConfig`: one model update,
:mod:`anigs.animate.update`) and ``final`` (:class:`FinalConfig`: the final videos,
:mod:`anigs.animate.final_videos`). The baselines' sub-sections: :mod:`anigs.animate.method_config`."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar

from anigs.effects.labels import effect_label_ids
from anigs.animate.method_config import LiftingConfig, PhysicsConfig
from anigs.animate.plan import RoundPlan
from anigs.typed_config import Section


@dataclass(frozen=True)
class AnimateConfig(Section):
    """``animate`` config section: how the dataset-model loop unrolls."""

    WHERE = "animate"
    ERROR = KeyError

    frames: int = 25  # T: frames per clip and of the DCT motion period
    views_per_round: int = 3  # views added to the dataset per round (paper: 1)
    extra_rounds: int = 0  # refresh rounds after every view is in the dataset
    view_expansion: bool = True  # false: every view from round 1 (ablation "w/o viewpoint expansion")
    dataset_update: bool = True  # false: targets generated once from the static model (ablation)
    method: str = "anigs"  # anigs (ours) | lifting (Gaussians2Life-style) | physics (PhysDreamer-style baseline)
    lifting: LiftingConfig = field(default_factory=LiftingConfig)  # the lifting baseline (method: lifting)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)  # the physics baseline (method: physics)

    def validate(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"animate.method must be one of {list(METHODS)}, got {self.method!r}")

    def plan(self, num_views: int) -> RoundPlan:
        """The rounds of this config. A baseline fits once: one round, every view in it, each
        view's target refined from the static render (what the paper's baselines are given)."""
        if self.method != "anigs":
            return RoundPlan(num_views, num_views, 0, view_expansion=False, dataset_update=False)
        return RoundPlan(num_views, self.views_per_round, self.extra_rounds, self.view_expansion, self.dataset_update)



# animate.method -> the method's name in the paper's tables
METHODS: dict[str, str] = {"anigs": "Ours", "lifting": "Gaussians2Life", "physics": "PhysDreamer"}


@dataclass
class RenderClipConfig(Section):
    """The ``render_clip`` config section."""

    HANDED = ('device', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    num_frames: int = 25  # frames per clip (the workflow passes animate.frames)
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour (RGB in [0,1])
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend: auto | cpu | torch | gsplat

    WHERE: ClassVar[str] = "render_clip config"
    ERROR: ClassVar[type[Exception]] = KeyError

    def validate(self) -> None:
        if self.num_frames < 1:
            raise ValueError(f"render_clip config: num_frames must be >= 1, got {self.num_frames}")
        if len(self.background) != 3:
            raise ValueError("render_clip config: background must be 3 numbers")


PARAM_GROUPS = ("deformation+positions", "deformation", "all")


@dataclass
class UpdateConfig(Section):
    """Hyper-parameters of one model update (the ``update`` config section)."""

    HANDED = ('seed', 'device', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "update config"
    ERROR = KeyError

    steps: int = 600  # optimisation steps per round
    views_per_step: int = 2  # (view, t) samples per step for the animation loss
    cano_views_per_step: int = 1  # views per step for the canonical loss (frame 0 vs the static render)
    num_bases: int = 16  # K: DCT bases per motion channel (clamped to T-1)
    rotation: bool = True  # learn per-Gaussian rotation offsets as well as position offsets
    #: trainable parameters: deformation+positions (paper) | deformation | all
    param_groups: str = "deformation+positions"
    lr_position_coeffs: float = 2e-3  # learning rate of the position DCT coefficients (times spatial_lr_scale)
    lr_rotation_coeffs: float = 5e-3  # learning rate of the rotation DCT coefficients
    lr_means: float = 2e-4  # learning rate of the canonical positions (times spatial_lr_scale)
    lr_quats: float = 1e-3  # learning rate of the rotations
    lr_scales: float = 5e-3  # learning rate of the log-scales
    lr_opacity: float = 2.5e-2  # learning rate of the opacity logits
    lr_sh: float = 2.5e-3  # learning rate of the SH coefficients (param_groups all)
    lr_final_factor: float = 0.1  # learning rates decay exponentially to this fraction at the last step
    #: length scale of position learning rates (null = 1-99 percentile scene extent)
    spatial_lr_scale: float | None = None
    lambda_cano: float = 0.1  # weight of the canonical loss
    lambda_sds: float = 0.0  # weight of the SDS loss (needs a prior with a score: ltx)
    sds_frames: int = 9  # frames of the SDS sub-clip (4m+1)
    #: smooth limit on offsets as a fraction of the height above the ground (null = none)
    max_offset_frac: float | None = None
    max_offset_abs: float | None = None  # smooth absolute limit on offsets in world units (null = none)
    max_angle_deg: float | None = None  # smooth limit on rotation offsets in degrees (null = none)
    effect_limits: dict = field(default_factory=dict)  # per-effect-label overrides of the three limits
    #: per-effect capacity, {key: K_e <= num_bases}: the Gaussians of that effect use only the first K_e DCT bases (the
    #: rest stay zero); key = a label of the masks stage's effect labels ("1", "2", ...; without them every dynamic Gaussian
    #: is "1") or an effect name (foliage_sway, leaf_flutter: label 1, grass_wave 2, flower_bob 3, water_ripple 4 = 1 +
    #: the effects stage's region index; effects sharing a label take their largest K_e, unnamed ones count as
    #: num_bases); {} = all use num_bases. Default: grass and flowers 6 (demo, labels from the masks stage: their
    #: amplitude W1 2.1x / 2.7x and frequency W1 1.8x / 1.9x lower than at 12, foliage unchanged, the same time:
    #: benchmarks/README.md)
    effect_num_bases: dict = field(default_factory=lambda: {"grass_wave": 6, "flower_bob": 6})
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour (RGB in [0,1])
    seed: int = 0  # random seed (the workflow passes the global seed)
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend: auto | cpu | torch | gsplat
    log_every: int = 25  # log the loss every this many steps
    nan_guard: bool = True  # stop on NaN loss or gradients, saving the last good state
    #: with the masks: after training, a Gaussian whose motion carries its footprint out of a view's dilated mask moves
    #: less (1/2, 1/4) or stays still
    contain: bool = True
    #: containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_margin_px: int = 3
    #: containment: most blending weight (in pixels) a moving Gaussian may put outside, in any frame and view (0.05
    #: left 1-3 levels of change on flower-llff)
    contain_max_outside_px: float = 0.01
    #: which rounds' updates contain the motion (the update stage decides from --round/--rounds): final (the model that is
    #: rendered, exported and evaluated; an earlier round's model only renders the next round's clips, whose static
    #: pixels ComposedV2V pastes back from frame 0) or every
    contain_rounds: str = "final"

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        if not d["effect_num_bases"]:  # opt-in key: unused, the recorded config is the one before it existed
            del d["effect_num_bases"]
        return d

    def validate(self) -> None:
        if self.param_groups not in PARAM_GROUPS:
            raise ValueError(f"update config: param_groups={self.param_groups!r}; choose one of {PARAM_GROUPS}")
        if self.steps < 0 or self.views_per_step < 1 or self.cano_views_per_step < 0:
            raise ValueError("update config: steps >= 0, views_per_step >= 1, cano_views_per_step >= 0 required")
        if self.num_bases < 0:
            raise ValueError(f"update config: num_bases must be >= 0, got {self.num_bases}")
        for k in ("lambda_cano", "lambda_sds"):
            if getattr(self, k) < 0:
                raise ValueError(f"update config: {k} must be >= 0")
        if self.sds_frames < 1 or self.sds_frames % 4 != 1:
            raise ValueError(f"update config: sds_frames must be 4m+1 (1, 5, 9, ...), got {self.sds_frames}")
        for f in fields(self):
            if f.name.startswith("lr_") and not (math.isfinite(getattr(self, f.name)) and getattr(self, f.name) > 0):
                raise ValueError(f"update config: {f.name} must be a finite positive number, got {getattr(self, f.name)}")
        if self.contain_margin_px < 0 or not self.contain_max_outside_px >= 0:
            raise ValueError("update config: contain_margin_px and contain_max_outside_px must be >= 0")
        if not 0 < self.lr_final_factor <= 1:
            raise ValueError("update config: lr_final_factor must be in (0, 1]")
        if len(self.background) != 3:
            raise ValueError("update config: background must be 3 numbers")
        if self.contain_rounds not in ("final", "every"):
            raise ValueError(f"update config: contain_rounds={self.contain_rounds!r}; choose final or every")
        for key, lim in self.effect_limits.items():
            bad = set(lim) - {"max_offset_frac", "max_offset_abs", "max_angle_deg"}
            if bad:
                raise KeyError(f"update config: effect_limits[{key!r}] has unknown key(s) {sorted(bad)}")
        if self.effect_num_bases:
            names = effect_label_ids()
            for key, k in self.effect_num_bases.items():
                if not (str(key) in names or (str(key).isdigit() and int(key) > 0)):
                    raise KeyError(f"update config: effect_num_bases key {key!r} is unknown: give an effect label "
                                   f"(1, 2, ... as a string) or an effect name ({', '.join(names)})")
                if isinstance(k, bool) or not isinstance(k, int) or k < 1:
                    raise ValueError(f"update config: effect_num_bases[{key!r}] = {k!r}: must be an integer >= 1 "
                                     f"(above num_bases = {self.num_bases} it changes nothing)")
            twice = {names[k] for k in self.effect_num_bases if k in names} & {
                int(k) for k in self.effect_num_bases if k not in names}
            if twice:
                raise ValueError(f"update config: effect_num_bases gives label(s) {sorted(twice)} both by number "
                                 "and by effect name")


@dataclass
class FinalConfig(Section):
    """``final`` config section."""

    HANDED = ('device', 'background', 'fps')  # set once for the whole run (anigs.config.HANDED), not in this section

    frames: int = 0  # frames per video (0 = the model's T); fractional times loop the DCT period
    fps: int = 12  # frames per second of the written videos / sidecar
    path_frames: int = 96  # frames of the moving-camera video
    path_loops: int = 2  # how many animation periods the moving camera sees
    path_views: int = 6  # capture cameras the path passes through (evenly picked)
    scale: float = 1.0  # resolution factor of the view videos
    #: RGB in [0,1] behind the splats, where the views show what no photo covered (a neutral grey; a
    #: synthetic scene's own sky: its scene file's `background`)
    background: list = field(default_factory=lambda: [0.5, 0.5, 0.5])
    slice_upsample: int = 4  # each time step becomes this many rows in slice PNGs
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)

    WHERE: ClassVar[str] = "final"
    ERROR: ClassVar[type[Exception]] = KeyError
