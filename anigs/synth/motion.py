"""Ground-truth wind motion of the synthetic garden (the truth learned motion is compared with).

Every movable Gaussian is displaced by a 3D offset that depends only on its canonical mean,
its anchor, its label and the time, so the motion is multi-view consistent by construction.
Time ``t`` is in frames; all temporal frequencies are whole cycles per clip of ``T`` frames,
so ``offsets(t + T) == offsets(t)`` (a loopable clip) and ``offsets(0) == 0`` exactly:
the captured scene *is* the canonical state.

Effect types (``EFFECT_TYPES``) and which labels carry them (``LABEL_EFFECTS``):

- ``foliage_sway``: tree crowns and bushes bend downwind about their anchor (trunk base,
  bush base); amplitude ``A (h / h_ref)^p`` with ``h`` the height above the anchor; a
  travelling gust wave (wavelength ``wavelength`` along the wind) keeps neighbours coherent.
- ``leaf_flutter``: small, fast, isotropic jitter of leaves with a short spatial wavelength,
  ramping in over ``h_ref`` above the anchor.
- ``grass_wave``: grass blades bend about their tuft root; a wave rolls over the lawn.
- ``flower_bob``: flower stems sway about the stem base and heads bob vertically.

- ``water_ripple`` (only with the optional pond, label ``water``): two travelling waves, one
  downwind and one across it (relative amplitude ``cross``), lift and lower the surface
  (``amplitude``, ``wavelength``, ``cycles``) with a small orbital motion along each wave
  (``vertical`` times the amplitude, a quarter period ahead). Its parameters and tables appear
  in ``motion.json`` only when the scene has a pond, so the default garden's stay as they were.

A bending offset also drops the point on an arc (``dz = -|d_xy|^2 / 2(h + 5 cm)``), so
swaying parts do not stretch. Static labels get exactly zero.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field

import torch

from anigs.typed_config import from_dict
from anigs.synth.scene import LABEL_IDS, LABELS, WATER_LABEL

EFFECT_TYPES: tuple[str, ...] = ("foliage_sway", "leaf_flutter", "grass_wave", "flower_bob")
LABEL_EFFECTS: dict[str, tuple[str, ...]] = {
    "ground": (), "building": (), "clutter": (), "trunk": (),
    "foliage": ("foliage_sway", "leaf_flutter"), "grass": ("grass_wave",), "flowers": ("flower_bob",),
}


WATER_EFFECT = "water_ripple"
ALL_EFFECT_TYPES: tuple[str, ...] = EFFECT_TYPES + (WATER_EFFECT,)
WATER_LABEL_EFFECTS: dict[str, tuple[str, ...]] = {"water": (WATER_EFFECT,)}


def motion_class(label_name: str) -> str:
    """``"static"`` or the '+'-joined effect types of a label (e.g. ``foliage_sway+leaf_flutter``)."""
    eff = {**LABEL_EFFECTS, **WATER_LABEL_EFFECTS}[label_name]
    return "+".join(eff) if eff else "static"


@dataclass
class EffectParams:
    """One effect: amplitude (m) at ``height_ref`` (m) above the anchor, growth power, whole cycles per
    clip, spatial wavelength (m), cross-wind ratio, vertical bob ratio.

    For ``leaf_flutter`` the envelope saturates at ``height_ref`` and ``cross``/``vertical`` are unused
    (flutter is isotropic)."""

    amplitude: float = 0.05
    height_ref: float = 3.0
    power: float = 1.5
    cycles: int = 1
    wavelength: float = 8.0
    cross: float = 0.35
    vertical: float = 0.0

    def __post_init__(self) -> None:
        if self.amplitude < 0 or self.height_ref <= 0 or self.power < 0 or self.wavelength <= 0:
            raise ValueError(f"effect parameters out of range: {self}")
        if self.cycles < 0:
            raise ValueError(f"effect cycles must be >= 0, got {self.cycles}")


def _default_effects() -> dict[str, EffectParams]:
    return {
        "foliage_sway": EffectParams(0.06, 3.0, 1.5, 1, 9.0, 0.35, 0.0),
        "leaf_flutter": EffectParams(0.012, 0.6, 1.0, 5, 0.7, 1.0, 1.0),
        "grass_wave": EffectParams(0.05, 0.25, 1.2, 2, 2.5, 0.3, 0.0),
        "flower_bob": EffectParams(0.04, 0.4, 1.2, 2, 3.0, 0.3, 0.3),
    }


def water_default() -> EffectParams:
    """Default ``water_ripple`` parameters: 1.5 cm waves of 0.6 m, 3 cycles per clip."""
    return EffectParams(0.015, 1.0, 1.0, 3, 0.6, 0.6, 0.3)


@dataclass
class MotionParams:
    """Wind motion parameters (config section ``synthetic.motion``)."""

    wind_dir_deg: float = 30.0  # direction the wind blows towards, degrees from +x towards +y
    frames: int = 25  # T: frames per loop
    fps: float = 12.5  # playback rate (metadata for videos): a loop lasts frames / fps seconds
    effects: dict = field(default_factory=_default_effects)

    def __post_init__(self) -> None:
        if self.frames < 2:
            raise ValueError(f"motion.frames must be >= 2, got {self.frames}")
        if self.fps <= 0:
            raise ValueError(f"motion.fps must be > 0, got {self.fps}")
        eff = dict(_default_effects())
        for name, val in self.effects.items():
            if name not in ALL_EFFECT_TYPES:
                raise ValueError(f"synthetic.motion.effects: unknown effect {name!r}; known: {list(ALL_EFFECT_TYPES)}")
            eff[name] = val if isinstance(val, EffectParams) else from_dict(
                EffectParams, val, f"synthetic.motion.effects.{name}", check_types=True)
        self.effects = eff

    @staticmethod
    def from_dict(d: dict | None) -> "MotionParams":
        d = dict(d or {})
        effects = d.pop("effects", {}) or {}
        p = from_dict(MotionParams, d, "synthetic.motion", check_types=True)
        return MotionParams(p.wind_dir_deg, p.frames, p.fps, effects)

    def to_dict(self) -> dict:
        return {"wind_dir_deg": self.wind_dir_deg, "frames": self.frames, "fps": self.fps,
                "effects": {k: asdict(v) for k, v in self.effects.items()}}


def _wave(p: EffectParams, t: torch.Tensor, T: int, phase: torch.Tensor, harmonic: int = 1,
          shift: float = 0.0) -> torch.Tensor:
    """sin(w t - phase + shift) - sin(-phase + shift), w = 2 pi cycles harmonic / T: [F,1] x [M] -> [F,M]."""
    w = 2 * math.pi * p.cycles * harmonic / T
    return torch.sin(w * t - phase + shift) - torch.sin(-phase + shift)


def _sway(p: EffectParams, means, anchors, t, T, wind: torch.Tensor, flutter: bool) -> torch.Tensor:
    """Offsets [F,M,3] of one effect for M points."""
    h = (means[:, 2] - anchors[:, 2]).clamp_min(0)
    if flutter:
        env = p.amplitude * (h / p.height_ref).clamp(max=1).pow(p.power)
        out = []
        dirs = torch.tensor([[0.8, 0.5, 0.33], [-0.45, 0.85, 0.27], [0.3, -0.2, 0.93]], dtype=means.dtype)
        dirs = dirs / dirs.norm(dim=1, keepdim=True)
        for i in range(3):
            ph = 2 * math.pi * (means @ dirs[i]) / p.wavelength
            out.append(env * _wave(p, t, T, ph, shift=1.7 * i))
        return torch.stack(out, -1)
    env = p.amplitude * (h / p.height_ref).pow(p.power)
    perp = torch.stack([-wind[1], wind[0]])
    ph = 2 * math.pi * (anchors[:, :2] @ wind) / p.wavelength
    along = 0.8 * _wave(p, t, T, ph) + 0.2 * _wave(p, t, T, 1.7 * ph, harmonic=2, shift=0.9)
    across = _wave(p, t, T, ph, shift=2.1)
    dxy = env[..., None] * (along[..., None] * wind + p.cross * across[..., None] * perp)
    dz = -(dxy**2).sum(-1) / (2 * (h + 0.05))
    if p.vertical > 0:
        dz = dz + p.vertical * env * _wave(p, t, T, ph, harmonic=2, shift=0.7)
    return torch.cat([dxy, dz[..., None]], -1)


def _ripple(p: EffectParams, means: torch.Tensor, t: torch.Tensor, T: int, wind: torch.Tensor) -> torch.Tensor:
    """Water offsets [F,M,3]: a wave downwind and one across it (``cross``), vertical + orbital."""
    out = torch.zeros(t.shape[0], means.shape[0], 3)
    perp = torch.stack([-wind[1], wind[0]])
    for d, amp, cyc in ((wind, 1.0, p.cycles), (perp, p.cross, p.cycles + 1)):
        q = dataclasses.replace(p, cycles=cyc)
        ph = 2 * math.pi * (means[:, :2] @ d) / p.wavelength
        a = p.amplitude * amp
        out[..., 2] += a * _wave(q, t, T, ph)
        out[..., :2] += (p.vertical * a * _wave(q, t, T, ph, shift=0.5 * math.pi))[..., None] * d
    return out


def gt_offsets(params: MotionParams, means: torch.Tensor, anchors: torch.Tensor, labels: torch.Tensor,
               t: float | torch.Tensor, T: int | None = None) -> torch.Tensor:
    """Ground-truth displacement of every Gaussian at time ``t`` (frames).

    Args:
        means [N,3] canonical positions; anchors [N,3]; labels [N] int (``LABELS``);
        t: a float / 0-d tensor (-> [N,3]) or a 1-D tensor of F times (-> [F,N,3]);
        T: loop length in frames (default ``params.frames``).
    Returns offsets (float32 like ``means``); rows of static labels are exactly 0.
    """
    T = params.frames if T is None else int(T)
    if T < 1:
        raise ValueError(f"gt_offsets: T must be >= 1, got {T}")
    means = torch.as_tensor(means, dtype=torch.float32)
    anchors = torch.as_tensor(anchors, dtype=torch.float32)
    labels = torch.as_tensor(labels)
    n = means.shape[0]
    if means.shape != (n, 3) or anchors.shape != (n, 3) or labels.shape != (n,):
        raise ValueError(f"gt_offsets: expected means [N,3], anchors [N,3], labels [N]; got "
                         f"{tuple(means.shape)}, {tuple(anchors.shape)}, {tuple(labels.shape)}")
    tt = torch.as_tensor(t, dtype=torch.float32)
    scalar = tt.ndim == 0
    tt = tt.reshape(-1, 1)
    a = math.radians(params.wind_dir_deg)
    wind = torch.tensor([math.cos(a), math.sin(a)], dtype=torch.float32)
    out = torch.zeros(tt.shape[0], n, 3)
    for name, effects in LABEL_EFFECTS.items():
        idx = torch.nonzero(labels == LABEL_IDS[name]).squeeze(1)
        if not effects or idx.numel() == 0:
            continue
        for eff in effects:
            out[:, idx] += _sway(params.effects[eff], means[idx], anchors[idx], tt, T, wind,
                                 flutter=(eff == "leaf_flutter"))
    water = torch.nonzero(labels == WATER_LABEL).squeeze(1)
    if water.numel():
        p = params.effects.get(WATER_EFFECT) or water_default()
        out[:, water] += _ripple(p, means[water], tt, T, wind)
    return out[0] if scalar else out


def gt_clip_offsets(params: MotionParams, means, anchors, labels, T: int | None = None) -> torch.Tensor:
    """Offsets for one loop: frames t = 0..T-1 -> [T,N,3]."""
    T = params.frames if T is None else int(T)
    return gt_offsets(params, means, anchors, labels, torch.arange(T, dtype=torch.float32), T)


def motion_tables(water: bool = False) -> dict:
    """Label and effect tables written next to the parameters in ``motion.json``.

    ``water``: the scene has the pond (``SceneConfig.pond``): adds the ``water`` label and
    ``water_ripple`` (without it the tables are exactly those of the default garden).
    """
    labels = {**LABELS, WATER_LABEL: "water"} if water else dict(LABELS)
    effects = {**LABEL_EFFECTS, **WATER_LABEL_EFFECTS} if water else LABEL_EFFECTS
    return {
        "labels": {str(i): name for i, name in labels.items()},
        "label_effects": {name: list(eff) for name, eff in effects.items()},
        "label_motion_class": {name: motion_class(name) for name in labels.values()},
        "effect_types": list(ALL_EFFECT_TYPES if water else EFFECT_TYPES),
        "movable_labels": [i for i, name in labels.items() if effects[name]],
        "static_labels": [i for i, name in labels.items() if not effects[name]],
        "time_unit": "frames; offsets periodic with period `frames`, zero at t=0 (canonical = captured state)",
    }
