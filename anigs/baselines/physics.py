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
from typing import Any, Mapping

import numpy as np
import torch

from anigs.animate.update import ViewData
from anigs.animate.method_config import PhysicsConfig
from anigs.baselines.base import BaselineResult, finish, prepare
from anigs.baselines.material import MaterialFit, WindResponse, fit_material, material_regions
from anigs.baselines.springs import build_graph
from anigs.baselines.tracks import observe_view, track_visibility
from anigs.gaussians import Gaussians

__all__ = ["MaterialFit", "PhysicsConfig", "WindResponse", "fit", "fit_material", "material_regions", "pick_view"]

log = logging.getLogger("anigs.baselines.physics")


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
    counts = [int(track_visibility(canonical, idx, v.camera, cfg.depth_tol, cfg.min_alpha, cfg.background,
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
