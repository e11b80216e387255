"""The configs of the comparison methods ``animate.method`` picks: the config sections
``animate.lifting`` (:mod:`anigs.baselines.lifting`) and ``animate.physics``
(:mod:`anigs.baselines.physics`). Here, not beside the baselines, so that the ``animate``
section parses without loading them (the workflow parses it when it builds the job graph)."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from anigs.typed_config import Section
from anigs.flow import PRESETS

INTEGRATORS = ("midpoint", "euler")  # the mass-spring integrators (anigs.baselines.springs)


@dataclass
class CommonConfig(Section):
    """The keys both baselines' configs share, their ``to_dict`` and checks."""

    HANDED = ('seed', 'device', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    ERROR = KeyError

    num_bases: int = 16            # DCT K of the output model (clamped to T-1)
    flow_preset: str = "medium"    # OpenCV DIS preset of the 2D motion: ultrafast | fast | medium
    fb_threshold_px: float = 1.0   # forward-backward flow check: tracks whose loop error exceeds this (px) are dropped
    depth_tol: float = 0.05        # visibility: projected depth <= rendered depth * (1 + depth_tol)
    min_alpha: float = 0.5         # visibility: rendered opacity at the Gaussian's pixel at least this
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour of the visibility renders
    backend: str = "auto"          # rasterizer backend of the visibility renders
    device: str = "auto"           # torch device of the visibility renders
    seed: int = 0                  # random seed (the fits are deterministic; kept for uniformity)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def validate(self) -> None:
        if self.num_bases < 0:
            raise ValueError(f"{type(self).__name__}: num_bases must be >= 0, got {self.num_bases}")
        if self.flow_preset not in PRESETS:
            raise ValueError(f"{type(self).__name__}: flow_preset {self.flow_preset!r} not in {sorted(PRESETS)}")
        if not self.fb_threshold_px > 0 or not self.depth_tol >= 0 or not 0 <= self.min_alpha < 1:
            raise ValueError(f"{type(self).__name__}: fb_threshold_px > 0, depth_tol >= 0, 0 <= min_alpha < 1 required")
        if len(self.background) != 3:
            raise ValueError(f"{type(self).__name__}: background must be 3 numbers")


@dataclass
class LiftingConfig(CommonConfig):
    """The lifting baseline's config (its workflow config section)."""

    WHERE = "animate.lifting"

    ridge: float = 1e-3          # Tikhonov weight relative to the mean squared Jacobian gain (px^2 per unit^2)
    fill_neighbors: int = 8      # Gaussians seen by no view: IDW mean of this many observed neighbours (0 = still)

    def validate(self) -> None:
        super().validate()
        if not self.ridge > 0:
            raise ValueError(f"LiftingConfig: ridge must be > 0, got {self.ridge}")
        if self.fill_neighbors < 0:
            raise ValueError(f"LiftingConfig: fill_neighbors must be >= 0, got {self.fill_neighbors}")


@dataclass
class PhysicsConfig(CommonConfig):
    """The physics baseline's config (its workflow config section)."""

    WHERE = "animate.physics"

    fps: float = 24.0                    # frame rate of the clips (the procedural prior's default)
    substeps: int = 4                    # integrator steps per frame
    integrator: str = "midpoint"         # midpoint (trapezoidal, energy-conserving) | euler (backward Euler)
    warmup_s: float = 1.0                # final simulation starts this long before frame 0 (in the steady state)
    k_neighbors: int = 8                 # springs per Gaussian (kNN)
    anchor_neighbors: int = 4            # anchor springs per Gaussian near the static scene
    anchor_radius: float = 1.5           # anchor reach, x median spring length
    regions_per_effect: int = 3          # k-means regions per effect label (material field resolution)
    wind_modes: int = 3                  # harmonics of the wind
    wind_freqs_hz: list = field(default_factory=list)  # explicit wind frequencies (Hz); empty = j * fps / T
    wind_dir_deg: float = 0.0            # travel direction of gusts (from +x towards +y)
    gust_speed: float = 0.0              # gust phase speed, scene units / s (0 = spatially uniform wind)
    stiffness_init: float = 100.0        # 1/s^2 per unit mass (sqrt = 10 rad/s, ~1.6 Hz)
    stiffness_bounds: list = field(default_factory=lambda: [1.0, 1e5])  # natural frequencies ~0.16-50 Hz
    damping_init: float = 2.0            # 1/s
    damping_bounds: list = field(default_factory=lambda: [1e-3, 1e3])  # search range of the damping (1/s)
    grid_stiffness: int = 16             # coarse start: shared stiffness values log-spaced over stiffness_bounds
    grid_damping: int = 3                # ... times shared damping values damping_init * 4^(j - (n-1)/2)
    sweeps: int = 1                      # coordinate sweeps after the grid: each log-parameter scanned alone
    scan_points: int = 13                # ... at this many values over +-1 decade around its current value
    max_evals: int = 100                 # Nelder-Mead evaluations to polish (0 = grid and sweeps only)
    wind_ridge: float = 1e-6             # ridge of the wind least squares, relative to the mean normal-matrix diagonal
    fit_view: str | int | None = None    # view id (camera name) or index; None = the view seeing most dynamic Gaussians

    def validate(self) -> None:
        super().validate()
        if not (self.fps > 0 and self.substeps >= 1 and self.warmup_s >= 0):
            raise ValueError("PhysicsConfig: fps > 0, substeps >= 1, warmup_s >= 0 required")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"PhysicsConfig: integrator {self.integrator!r} not in {INTEGRATORS}")
        if self.regions_per_effect < 1 or self.wind_modes < 1 or self.max_evals < 0:
            raise ValueError("PhysicsConfig: regions_per_effect >= 1, wind_modes >= 1, max_evals >= 0 required")
        for name in ("stiffness_bounds", "damping_bounds"):
            lo, hi = getattr(self, name)
            if not (0 < lo < hi and math.isfinite(hi)):
                raise ValueError(f"PhysicsConfig: {name} must be [lo, hi] with 0 < lo < hi, got {[lo, hi]}")
        if not self.stiffness_bounds[0] <= self.stiffness_init <= self.stiffness_bounds[1]:
            raise ValueError("PhysicsConfig: stiffness_init outside stiffness_bounds")
        if not self.damping_bounds[0] <= self.damping_init <= self.damping_bounds[1]:
            raise ValueError("PhysicsConfig: damping_init outside damping_bounds")
        if any(not (f > 0 and math.isfinite(f)) for f in self.wind_freqs_hz):
            raise ValueError(f"PhysicsConfig: wind_freqs_hz must be positive, got {self.wind_freqs_hz}")
        if self.gust_speed < 0:
            raise ValueError("PhysicsConfig: gust_speed must be >= 0")
        if self.grid_stiffness < 1 or self.grid_damping < 1 or self.sweeps < 0 or self.scan_points < 2:
            raise ValueError("PhysicsConfig: grid_stiffness >= 1, grid_damping >= 1, sweeps >= 0, scan_points >= 2 required")
