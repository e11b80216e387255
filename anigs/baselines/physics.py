"""PhysDreamer-style baseline: a simulated material response fitted to the video prior of one view.

The AniGS paper (Sec. "Baselines") describes it as: "PhysDreamer instead distills
diffusion-predicted motion into physically grounded dynamics by optimizing material parameters
of a differentiable simulator (MPM) so that simulated renderings match generated video clips",
run "with a shared training view due to their object-centric setup" (Zhang et al. 2024).

This version, from the same inputs as our model update:

1. **System**: the dynamic Gaussians become a mass-spring system (:mod:`anigs.baselines.springs`):
   kNN springs among them, anchor springs to nearby static Gaussians (fixed), every component
   anchored. Only the dynamic set is simulated, so only the effects the scene contains move;
   static Gaussians never do.
2. **Material field**: per-region stiffness k_r (1/s^2) and damping c_r (1/s); the regions
   are ``regions_per_effect`` k-means clusters of each effect label in the dynamic mask (a
   boolean mask is one effect).
3. **Wind**: a horizontal force field, the sum of ``wind_modes`` harmonics (default: the clip's
   lowest harmonics, ``j fps / T`` Hz) with free amplitudes and phases per horizontal axis,
   spatially uniform or travelling along ``wind_dir_deg`` at ``gust_speed``. Frame 0 is a state
   inside the steady sway, not a start from rest; displacements are taken relative to frame 0,
   like the targets' motion.
4. **Fit to one view's refined clip**: the 2D tracks (forward optical flow from frame 0,
   forward-backward checked) at the Gaussians that view sees are compared with the simulated
   displacements projected through the view's Jacobians. The system is linear in the wind, so
   for given (k, c) the wind amplitudes are the closed-form ridge least-squares solution, on
   the exact periodic steady state (one complex sparse solve per harmonic); the 2R
   log-parameters (k_r, c_r) are fitted by a coarse grid, coordinate scans and a Nelder-Mead
   polish. The trajectories then come from the implicit time integration (started in that
   steady state), with the wind re-solved on the simulated responses. The view is ``fit_view``
   (id or index), by default the one that sees most dynamic Gaussians.
5. **Simulation**: an implicit integrator (:class:`~anigs.baselines.springs.ImplicitIntegrator`:
   trapezoidal/midpoint by default, backward Euler as an option), unconditionally stable for
   stiff springs and large steps, started ``warmup_s`` before frame 0 in the steady state; the
   displacements at the frames are projected on the DCT basis (:mod:`anigs.baselines.base`).

Where it differs from PhysDreamer: a linearised mass-spring graph instead of MPM with a
Young's-modulus field; per-region rather than per-point material; the excitation is a fitted
wind forcing rather than a fitted initial velocity (scenes sway in wind rather than being
poked); the loss compares optical-flow tracks with projected displacements instead of a
photometric loss on rendered frames, and the gradient-free fit of the few material parameters
(the wind is solved in closed form) replaces back-propagation through the simulator; the video
is our prior's refined clip of the view, not a separately generated one.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
import torch

from anigs.animate.update import ViewData
from anigs.baselines.base import BaselineResult, CommonConfig, finish, prepare
from anigs.baselines.material import MaterialFit, WindResponse, fit_material, material_regions
from anigs.baselines.springs import SCHEMES, build_graph
from anigs.baselines.tracks import observe_view, visibility
from anigs.gaussians import Gaussians

__all__ = ["MaterialFit", "PhysicsConfig", "WindResponse", "fit", "fit_material", "material_regions", "pick_view"]

log = logging.getLogger("anigs.baselines.physics")


@dataclass
class PhysicsConfig(CommonConfig):
    """The physics baseline's config (its workflow config section)."""

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
        if self.integrator not in SCHEMES:
            raise ValueError(f"PhysicsConfig: integrator {self.integrator!r} not in {SCHEMES}")
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


def pick_view(canonical: Gaussians, idx: torch.Tensor, views: list[ViewData], cfg: PhysicsConfig) -> int:
    """Index of the fit view: ``cfg.fit_view`` (id or index), else the one seeing most dynamic Gaussians."""
    if cfg.fit_view is not None:
        if isinstance(cfg.fit_view, int) and not isinstance(cfg.fit_view, bool):
            if not 0 <= cfg.fit_view < len(views):
                raise ValueError(f"physics baseline: fit_view {cfg.fit_view} out of range for {len(views)} views")
            return cfg.fit_view
        names = [v.camera.name for v in views]
        if str(cfg.fit_view) not in names:
            raise ValueError(f"physics baseline: fit_view {cfg.fit_view!r} is not one of the views {names}")
        return names.index(str(cfg.fit_view))
    counts = [int(visibility(canonical, idx, v.camera, cfg.depth_tol, cfg.min_alpha, cfg.background,
                             cfg.backend)[0].sum()) for v in views]
    return int(np.argmax(counts))


def fit(canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData],
        config: PhysicsConfig | Mapping[str, Any] | None = None) -> BaselineResult:
    """Fit the material field and the wind to one view's refined clip, then simulate (module docstring).

    Args:
        canonical: G^0 (N); dynamic_mask: [N] bool or int effect labels (0 = static);
        views: refined clips [T,H,W,3] with cameras (one is used, see ``fit_view``);
        config: :class:`PhysicsConfig` keys.
    Returns:
        :class:`BaselineResult`; info holds the fit view, the per-region stiffness/damping, the
        wind amplitudes and the relative residual before/after the material fit.
    """
    t0 = time.perf_counter()
    cfg, idx, T, canonical, shown = prepare(PhysicsConfig, config, canonical, dynamic_mask, views, "physics baseline")
    mask = torch.as_tensor(dynamic_mask)
    info: dict[str, Any] = {"method": "physics"}
    if idx.numel() == 0 or T < 2:
        info["skipped"] = "empty dynamic set" if idx.numel() == 0 else "single-frame clips"
        log.info("physics baseline: %s: nothing is simulated", info["skipped"])
        pts0 = canonical.means.double()[idx]
        return finish(canonical, idx, pts0[None].expand(T, -1, -1).clone(), cfg.num_bases, info, t0)
    means = canonical.means.double().numpy()
    X = means[idx.numpy()]
    static = np.ones(canonical.num, bool)
    static[idx.numpy()] = False
    graph = build_graph(X, means[static], cfg.k_neighbors, cfg.anchor_neighbors, cfg.anchor_radius)
    labels = mask[idx].long().numpy() if mask.dtype != torch.bool else np.ones(idx.numel(), np.int64)
    region, region_label = material_regions(X, labels, cfg.regions_per_effect)
    R = len(region_label)
    vi = pick_view(shown, idx, views, cfg)
    view = views[vi]
    obs = observe_view(shown, idx, view.camera, np.asarray(view.clip, np.float32), cfg.flow_preset,
                       cfg.fb_threshold_px, cfg.depth_tol, cfg.min_alpha, cfg.background, cfg.backend)
    sel = np.nonzero(obs.visible)[0]
    if len(sel) == 0:
        raise ValueError(f"physics baseline: the fit view {view.camera.name!r} sees none of the {idx.numel()} "
                         "dynamic Gaussians; choose another fit_view")
    fitres = fit_material(graph, region, R, obs, sel, cfg, T)
    a, U, wind = fitres.amplitudes, fitres.responses, fitres.wind
    loss0, loss, nfev = fitres.loss_initial, fitres.loss, fitres.evaluations
    B = U.shape[2]
    amp = a.reshape(B, 2)                                        # [B, (x, y)]
    disp = np.zeros((T, idx.numel(), 3))
    disp[..., :2] = np.einsum("tdb,ba->tda", U, amp)
    traj = torch.from_numpy(X[None] + disp)
    k_r, c_r = fitres.stiffness, fitres.damping
    info.update({"fit_view": view.camera.name, "visible_in_fit_view": int(len(sel)), "regions": R,
                 "region_labels": region_label, "region_sizes": np.bincount(region, minlength=R).tolist(),
                 "stiffness": k_r.tolist(), "damping": c_r.tolist(),
                 "wind_freqs_hz": (wind.omega / (2 * math.pi)).tolist(), "wind_amplitudes": amp.tolist(),
                 "relative_residual_initial": loss0, "relative_residual": loss, "evaluations": nfev,
                 "springs": int(len(graph.edges)), "anchor_springs": int(len(graph.anchor_node))})
    res = finish(canonical, idx, traj, cfg.num_bases, info, t0)
    log.info("physics baseline: view %s (%d visible), %d regions, residual %.3f -> %.3f in %d evaluations, %.1f s",
             view.camera.name, len(sel), R, loss0, loss, nfev, res.seconds)
    return res
