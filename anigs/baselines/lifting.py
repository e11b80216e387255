"""Gaussians2Life-style baseline: per-view 2D motion lifted to per-Gaussian 3D trajectories.

The AniGS paper (Sec. "Baselines") describes it as: "Gaussians2Life animates a static 3DGS by
generating multi-view diffusion guidance and lifting the induced 2D motion into 3D via tracked
points and depth alignment to drive Gaussian deformations" (Wimmer et al. 2025). No deformation
field is optimised against the videos; the motion comes from the 2D tracks alone.

This version, from the same inputs as our model update (canonical Gaussians, dynamic set,
the round's refined camera-fixed clips and their cameras):

1. **2D motion**: for each view, forward optical flow from frame 0 to every frame t (OpenCV
   DIS, :func:`anigs.baselines.tracks.forward_tracks`), with a forward-backward consistency
   check that drops occluded or failed tracks.
2. **Which Gaussians a view sees**: the centre of a dynamic Gaussian projects into the image,
   the canonical render is opaque there and its depth is at most the *rendered* depth there
   (times ``1 + depth_tol``). Its track is the flow sampled at its pixel.
3. **Lifting through the rendered depth, combining the views**: each visible view v gives
   ``J_v Δ ≈ d_v(t)``, with J_v [2,3] the projection Jacobian at the Gaussian's position (at
   its rendered depth) and d_v(t) its 2D displacement. The 3D displacement Δ(t) is the
   weighted least-squares solution over all views that see it, with a small ridge
   (``ridge`` x the mean squared Jacobian gain) so that a Gaussian seen by one view moves
   parallel to that image plane (the depth component is unobservable there). Views that
   disagree (a video prior run independently per view) are averaged in 3D.
4. **Animation**: trajectories ``x_i + Δ_i(t)``; Gaussians no view sees at frame t take the
   inverse-distance mean of their ``fill_neighbors`` nearest observed dynamic neighbours
   (0: they stay still). Only the dynamic set moves. The trajectories are projected on the
   DCT basis (:mod:`anigs.baselines.base`) so that the result renders, exports and evaluates
   like our model.

Where it differs from Gaussians2Life: the 2D motion is dense optical flow from frame 0
instead of a learned point tracker (CoTracker); the depth is the canonical scene's rendered
depth, so no monocular depth estimate has to be aligned to it (the alignment step becomes
unnecessary); views are combined by a per-Gaussian least-squares triangulation of the
displacement instead of optimising the Gaussians against the lifted tracks with
regularisers; the refined clips come from our prior (the same targets our model trains on),
not from Gaussians2Life's own multi-view generation; and the output is truncated to K DCT
bases (K = T-1 keeps the trajectories exactly).
"""
from __future__ import annotations

import logging
import time
from typing import Any, Mapping

import numpy as np
import torch

from anigs.animate.update import ViewData
from anigs.animate.method_config import LiftingConfig
from anigs.baselines.base import BaselineResult, finish, prepare
from anigs.baselines.tracks import observe_view
from anigs.gaussians import Gaussians

log = logging.getLogger("anigs.baselines.lifting")


def lift_displacements(jac: np.ndarray, disp: np.ndarray, weight: np.ndarray, ridge: float = 1e-3
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Per-Gaussian weighted least-squares 3D displacements from V views.

    Args:
        jac: [V,D,2,3] projection Jacobians; disp: [V,T,D,2] 2D displacements (px);
        weight: [V,T,D] >= 0 (0 = not observed); ridge: relative Tikhonov weight.
    Returns:
        (displacements [T,D,3] float64, observed [T,D] bool: some view has weight > 0).
    Solves ``(sum_v w J^T J + lam I) Δ = sum_v w J^T d`` with ``lam = ridge * s``, s the
    weighted mean of ``tr(J^T J) / 2`` over the observing views.
    """
    jac = np.asarray(jac, np.float64)
    disp = np.asarray(disp, np.float64)
    w = np.asarray(weight, np.float64)
    jtj = np.einsum("vdki,vdkj->vdij", jac, jac)                        # [V,D,3,3]
    A = np.einsum("vtd,vdij->tdij", w, jtj)                             # [T,D,3,3]
    b = np.einsum("vtd,vdki,vtdk->tdi", w, jac, disp)                   # [T,D,3]
    wsum = w.sum(0)                                                     # [T,D]
    gain = np.einsum("vtd,vd->td", w, np.trace(jtj, axis1=-2, axis2=-1) / 2.0) / np.maximum(wsum, 1e-300)
    lam = ridge * np.where(wsum > 0, gain, 1.0)
    A = A + lam[..., None, None] * np.eye(3)
    delta = np.linalg.solve(A, b[..., None])[..., 0]
    observed = wsum > 0
    delta[~observed] = 0.0
    return delta, observed


def fill_unobserved(points: np.ndarray, delta: np.ndarray, observed: np.ndarray, k: int) -> np.ndarray:
    """Displacements [T,D,3] where ``observed`` [T,D] is False replaced by the inverse-distance
    mean of the k nearest observed Gaussians (positions points [D,3]) at the same t; k = 0 or
    no observed Gaussian at t leaves them at 0."""
    from scipy.spatial import cKDTree

    out = delta.copy()
    if k <= 0:
        return out
    for t in range(delta.shape[0]):
        obs = np.nonzero(observed[t])[0]
        miss = np.nonzero(~observed[t])[0]
        if len(obs) == 0 or len(miss) == 0:
            continue
        kk = min(k, len(obs))
        dist, nn = cKDTree(points[obs]).query(points[miss], k=kk)
        dist, nn = dist.reshape(len(miss), kk), nn.reshape(len(miss), kk)
        w = 1.0 / np.maximum(dist, 1e-9)
        w /= w.sum(1, keepdims=True)
        out[t, miss] = (w[..., None] * delta[t, obs[nn]]).sum(1)
    return out


def fit(canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData],
        config: LiftingConfig | Mapping[str, Any] | None = None) -> BaselineResult:
    """Lift the views' 2D motion to per-Gaussian 3D trajectories (module docstring).

    Args:
        canonical: G^0 (N Gaussians); dynamic_mask: [N] bool or int labels (0 = static);
        views: refined clips [T,H,W,3] with their cameras (all used); config: :class:`LiftingConfig` keys.
    Returns:
        :class:`BaselineResult` (trajectories [T,D,3] float64; info: per-view visible counts,
        observed fraction, seconds).
    """
    t0 = time.perf_counter()
    cfg, idx, T, canonical, shown = prepare(LiftingConfig, config, canonical, dynamic_mask, views, "lifting baseline")
    pts = canonical.means.double().numpy()[idx.numpy()]
    info: dict[str, Any] = {"method": "lifting", "views": [v.camera.name for v in views]}
    if idx.numel() == 0:
        log.info("lifting baseline: the dynamic set is empty: nothing moves")
        info["skipped"] = "empty dynamic set"
        return finish(canonical, idx, torch.zeros(T, 0, 3, dtype=torch.float64), cfg.num_bases, info, t0)
    obs = []
    for v in views:
        o = observe_view(shown, idx, v.camera, np.asarray(v.clip, np.float32), cfg.flow_preset,
                         cfg.fb_threshold_px, cfg.depth_tol, cfg.min_alpha, cfg.background, cfg.backend)
        obs.append(o)
        log.info("lifting: view %s sees %d of %d dynamic Gaussians (%.0f%% of their tracks consistent)",
                 v.camera.name, int(o.visible.sum()), idx.numel(),
                 100.0 * o.weight[1:].sum() / max(o.visible.sum() * max(T - 1, 1), 1))
    jac = np.stack([o.jac for o in obs])
    disp = np.stack([o.disp for o in obs])
    weight = np.stack([o.weight for o in obs])
    delta, observed = lift_displacements(jac, disp, weight, cfg.ridge)
    delta[0] = 0.0
    observed[0] = True  # frame 0 is the canonical frame: zero displacement is known
    delta = fill_unobserved(pts, delta, observed, cfg.fill_neighbors)
    traj = torch.from_numpy(pts[None] + delta)
    n_views = np.stack([o.visible for o in obs]).sum(0)
    info.update({"visible_per_view": [int(o.visible.sum()) for o in obs],
                 "seen_by_no_view": int((n_views == 0).sum()), "seen_by_two_or_more": int((n_views >= 2).sum()),
                 "observed_fraction": float(observed[1:].mean()) if T > 1 else 1.0})
    res = finish(canonical, idx, traj, cfg.num_bases, info, t0)
    log.info("lifting baseline: %d dynamic Gaussians, %d seen by no view, RMS displacement %.4g, %.1f s",
             idx.numel(), info["seen_by_no_view"], info.get("displacement_rms", 0.0), res.seconds)
    return res
