"""The static fit's budget: how many steps and Gaussians a capture gets, and what they cost here.

One dial, ``static.budget``: a named level or a number of minutes on this machine.

- ``fast``: a first look whatever the capture (anigs 0.7's defaults: 1,500 steps, 30,000 Gaussians).
- ``auto`` (the default): steps and Gaussians grow with the capture: ``epochs`` passes over the
  training photos, and a Gaussian budget proportional to the training pixels (``per_megapixel``
  Gaussians per training megapixel), each clamped to the level's range.
- ``quality``: the 3DGS 7k schedule's scale, for a user with hours to spare.
- a number: the largest schedule of the ``auto`` shape whose estimated time fits that many minutes.

Keys set explicitly in the section win over the level (``static.iterations``,
``static.densify.max_gaussians``, ``static.densify.stop``). The fit ends early when its held-out
curve flattens (``static.plateau_db``), so a level's steps are an upper bound.

The time estimate: a step costs ``a + b * pixels + c * Gaussians + d * pixels * Gaussians`` seconds
(:class:`StepCost`; the least-squares fit of ``benchmarks/fit_cost.py``, whose table is in
benchmarks/README.md, "What the static fit costs"); :func:`calibrate` times a few steps of the fit
itself on this machine before training and scales the model by the measured / predicted ratio,
so the estimate in the log is for this machine under its current load.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any, Sequence

from anigs.images import fit_scale

LEVELS_ORDER = ("fast", "auto", "quality")
AUTO_SIDE = 640  # the auto level's largest photo side (px): the views and clips are 256x192 by default


@dataclass(frozen=True)
class Level:
    """A named budget: steps and Gaussians as functions of the capture."""

    name: str
    epochs: float  # steps per training photo
    min_steps: int
    max_steps: int
    per_megapixel: float  # Gaussians per training megapixel (at the fit's image size)
    min_gaussians: int
    max_gaussians: int
    max_side: int = 0  # the fit's photos are downscaled to at most this longest side (0: as captured)

    def steps(self, photos: int) -> int:
        return int(min(max(round(self.epochs * photos / 100.0) * 100, self.min_steps), self.max_steps))

    def gaussians(self, megapixels: float) -> int:
        n = round(self.per_megapixel * megapixels / 1000.0) * 1000
        return int(min(max(n, self.min_gaussians), self.max_gaussians))


LEVELS: dict[str, Level] = {
    "fast": Level("fast", epochs=0, min_steps=1500, max_steps=1500, per_megapixel=0,
                  min_gaussians=30000, max_gaussians=30000),
    "auto": Level("auto", epochs=120, min_steps=1500, max_steps=4000, per_megapixel=10000,
                  min_gaussians=30000, max_gaussians=150000, max_side=AUTO_SIDE),
    "quality": Level("quality", epochs=300, min_steps=4000, max_steps=7000, per_megapixel=40000,
                     min_gaussians=100000, max_gaussians=300000),
}


@dataclass(frozen=True)
class CaptureSize:
    """What the budget follows: the training photos and their size."""

    photos: int  # training photos
    width: int  # median photo width (px)
    height: int  # median photo height (px)

    @property
    def pixels(self) -> int:
        """Pixels of one photo."""
        return self.width * self.height

    @property
    def megapixels(self) -> float:
        """Training megapixels (all photos)."""
        return self.photos * self.pixels / 1e6

    def limited(self, max_side: int) -> "CaptureSize":
        """The size after downscaling to at most ``max_side`` on the longest side (0: unchanged)."""
        f = fit_scale(self.width, self.height, max_side)
        return replace(self, width=max(1, round(self.width * f)), height=max(1, round(self.height * f)))

    @staticmethod
    def of(sizes: Sequence[tuple[int, int]]) -> "CaptureSize":
        """From the training photos' (width, height)."""
        ws = sorted(w for w, _ in sizes)
        hs = sorted(h for _, h in sizes)
        return CaptureSize(len(sizes), ws[len(ws) // 2], hs[len(hs) // 2])


@dataclass(frozen=True)
class StepCost:
    """Seconds per training step: ``scale * (a + b * pixels + c * gaussians + d * pixels * gaussians)``
    (the last term: larger splats on larger photos cover more pixels each). The coefficients are one
    thread's CPU seconds measured by ``benchmarks/fit_cost.py`` on the street walk with the ellipse-culled
    rasterizer (anigs 0.9; 12 points, 76k-697k pixels, 20k-150k Gaussians, within 11%); ``scale`` brings
    them to this machine and its threads."""

    a: float = 2.28e-3  # fixed part (s)
    b: float = 2.3e-7  # per pixel of the photo (s)
    c: float = 7.7e-7  # per Gaussian (s)
    d: float = 3.49e-12  # per pixel and Gaussian (s)
    scale: float = 1.0  # measured / predicted on this machine (:meth:`calibrated`)

    def _model(self, pixels: int, gaussians: float) -> float:
        return self.a + self.b * pixels + self.c * gaussians + self.d * pixels * gaussians

    def step(self, pixels: int, gaussians: float) -> float:
        return self.scale * self._model(pixels, gaussians)

    def fit_seconds(self, pixels: int, steps: int, start_gaussians: int, max_gaussians: int, densify_stop: int) -> float:
        """Estimated training seconds: the Gaussian count grows linearly from its start to the
        budget until densification stops (what the fits on the shared captures showed, to within
        a factor 1.5), then stays."""
        grow = min(densify_stop, steps)
        n_end = max(max_gaussians, start_gaussians)
        mean_grow = (start_gaussians + n_end) / 2.0
        return grow * self.step(pixels, mean_grow) + max(steps - grow, 0) * self.step(pixels, n_end)

    def calibrated(self, measured: float, pixels: int, gaussians: int) -> "StepCost":
        """This model scaled so it predicts ``measured`` seconds for a step at (pixels, gaussians)."""
        pred = self._model(pixels, gaussians)
        scale = measured / pred if pred > 0 and math.isfinite(measured) and measured > 0 else 1.0
        return replace(self, scale=scale)


@dataclass(frozen=True)
class FitPlan:
    """A concrete schedule for one fit, and its estimated cost on this machine."""

    level: str  # fast / auto / quality, or "N min"
    max_side: int  # the fit's photos' longest side at most (0: as captured)
    iterations: int
    max_gaussians: int
    densify_stop: int
    eval_every: int
    estimated_seconds: float  # training only (evaluations and the final pass excluded)
    pinned: tuple[str, ...] = ()  # keys the config set explicitly (they won over the level)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["pinned"] = list(self.pinned)
        d["estimated_seconds"] = round(self.estimated_seconds, 1)
        return d


def parse_budget(value: Any) -> str | float:
    """A level name or minutes (> 0); anything else raises ValueError naming ``static.budget``."""
    if isinstance(value, bool):
        raise ValueError(f"static.budget must be one of {list(LEVELS_ORDER)} or minutes (> 0), got {value!r}")
    if isinstance(value, (int, float)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"static.budget: minutes must be > 0, got {value!r}")
        return float(value)
    if isinstance(value, str) and value in LEVELS:
        return value
    raise ValueError(f"static.budget must be one of {list(LEVELS_ORDER)} or minutes (> 0), got {value!r}")


def _eval_every(iterations: int, explicit: int | None) -> int:
    if explicit is not None:
        return explicit
    return max(250, int(round(iterations / 8 / 250.0)) * 250)  # about 8 points on the curve


def _densify_stop(iterations: int, explicit: int | None, fraction: float) -> int:
    return explicit if explicit is not None else int(fraction * iterations)


def plan(budget: str | float, size: CaptureSize, cost: StepCost, start_gaussians: int, *,
         iterations: int | None = None, max_gaussians: int | None = None, densify_stop: int | None = None,
         stop_fraction: float = 0.8, eval_every: int | None = None, max_side: int | None = None) -> FitPlan:
    """The fit's schedule for ``budget`` on a capture of ``size`` (the photos as captured); explicit
    keys win. ``cost`` is per pixel of the fit's image size.

    ``start_gaussians``: the initial count (the SfM points), for the time estimate.
    """
    budget = parse_budget(budget)
    pinned = tuple(k for k, v in (("iterations", iterations), ("densify.max_gaussians", max_gaussians),
                                  ("densify.stop", densify_stop), ("max_side", max_side)) if v is not None)

    def build(level: Level, name: str, factor: float = 1.0) -> FitPlan:
        side = max_side if max_side is not None else level.max_side
        fit = size.limited(side)
        its = iterations if iterations is not None else max(100, int(round(level.steps(fit.photos) * factor)))
        gs = max_gaussians if max_gaussians is not None else max(
            start_gaussians, int(round(level.gaussians(fit.megapixels) * factor)))
        stop = _densify_stop(its, densify_stop, stop_fraction)
        secs = cost.fit_seconds(fit.pixels, its, start_gaussians, gs, stop)
        return FitPlan(name, side, its, gs, stop, _eval_every(its, eval_every), secs, pinned)

    if isinstance(budget, str):
        return build(LEVELS[budget], budget)
    # minutes: the auto shape scaled (steps and Gaussians alike) to fit, between 10% and 4x of auto
    target = budget * 60.0
    lo, hi = 0.1, 4.0
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        if build(LEVELS["auto"], "", mid).estimated_seconds > target:
            hi = mid
        else:
            lo = mid
    return build(LEVELS["auto"], f"{budget:g} min", lo)


def next_level(level: str) -> str | None:
    """The level above ``level`` (None above quality; after a minutes budget: quality)."""
    if level not in LEVELS:
        return "quality"
    i = LEVELS_ORDER.index(level)
    return LEVELS_ORDER[i + 1] if i + 1 < len(LEVELS_ORDER) else None
