"""2D motion of a refined clip and the geometry that ties it to Gaussians (shared by the baselines).

- :func:`forward_tracks`: for every pixel p of frame 0, where its content is in frame t,
  ``p + d_t(p)`` (OpenCV DIS from frame 0 to frame t, no chaining, so no drift), with a
  forward-backward consistency flag (occlusions and flow failures fail it).
- :func:`observe_view`: the dynamic Gaussians one view sees (projected depth against the
  rendered depth of the canonical scene), their pixels, and their tracks sampled there.
- :func:`projection_jacobians`: d(pixel)/d(world position) [D,2,3] of the pinhole projection,
  to relate 2D displacements to 3D ones.

Pixel convention (:mod:`anigs.cameras`): pixel centres at integer + 0.5, so array element
(row y, col x) is sampled at continuous position (x + 0.5, y + 0.5).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.flow import backward_flow, warp
from anigs.gaussians import Gaussians
from anigs.render import render_gaussians


def forward_tracks(clip: np.ndarray, preset: str = "medium", fb_threshold_px: float = 1.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Forward displacements [T,H,W,2] (px, ``d[0] = 0``) and validity [T,H,W] bool of a clip [T,H,W,3].

    ``clip[0](p) ≈ clip[t](p + d[t](p))``; valid where the backward flow brings ``p + d`` back
    to p within ``fb_threshold_px``.
    """
    clip = np.asarray(clip, np.float32)
    T, H, W, _ = clip.shape
    disp = np.zeros((T, H, W, 2), np.float32)
    valid = np.ones((T, H, W), bool)
    for t in range(1, T):
        fwd = backward_flow(clip[0], clip[t], preset)   # clip[0](p) ≈ clip[t](p + fwd(p))
        bwd = backward_flow(clip[t], clip[0], preset)   # clip[t](q) ≈ clip[0](q + bwd(q))
        loop = fwd + warp(bwd, fwd)                     # bwd sampled at p + fwd(p)
        disp[t] = fwd
        valid[t] = np.sqrt((loop ** 2).sum(-1)) <= fb_threshold_px
    return disp, valid


def sample_bilinear(field: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``field`` [T,H,W,C] at continuous pixel positions uv [D,2] -> [T,D,C]
    (positions clamped to the image, pixel centres at integer + 0.5)."""
    T, H, W = field.shape[:3]
    x = np.clip(uv[:, 0] - 0.5, 0.0, W - 1.0)
    y = np.clip(uv[:, 1] - 0.5, 0.0, H - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), max(W - 2, 0))
    y0 = np.minimum(np.floor(y).astype(np.int64), max(H - 2, 0))
    x1, y1 = np.minimum(x0 + 1, W - 1), np.minimum(y0 + 1, H - 1)
    wx, wy = (x - x0)[None, :, None], (y - y0)[None, :, None]
    f = field.astype(np.float64)
    return ((1 - wy) * ((1 - wx) * f[:, y0, x0] + wx * f[:, y0, x1])
            + wy * ((1 - wx) * f[:, y1, x0] + wx * f[:, y1, x1]))


def projection_jacobians(points: np.ndarray, camera: Camera) -> np.ndarray:
    """Jacobians [D,2,3] of the pixel position with respect to the world position at points [D,3].

    With p = R x + t: du/dp = (fx/z, 0, -fx p_x/z^2), dv/dp = (0, fy/z, -fy p_y/z^2); J = (du,dv)/dp @ R.
    """
    p = np.asarray(points, np.float64) @ camera.R.T + camera.t
    z = np.where(np.abs(p[:, 2]) < 1e-9, 1e-9, p[:, 2])
    fx, fy = camera.K[0, 0], camera.K[1, 1]
    jp = np.zeros((len(p), 2, 3))
    jp[:, 0, 0] = fx / z
    jp[:, 0, 2] = -fx * p[:, 0] / z ** 2
    jp[:, 1, 1] = fy / z
    jp[:, 1, 2] = -fy * p[:, 1] / z ** 2
    return jp @ camera.R


@dataclass
class ViewObservation:
    """What one view tells about the dynamic Gaussians.

    visible [D] bool; uv [D,2] pixel positions at frame 0; disp [T,D,2] forward displacements
    (px) sampled there; weight [T,D] in {0,1} (visible and forward-backward consistent);
    jac [D,2,3] projection Jacobians; depth [D] camera-space depth.
    """

    camera: Camera
    visible: np.ndarray
    uv: np.ndarray
    disp: np.ndarray
    weight: np.ndarray
    jac: np.ndarray
    depth: np.ndarray


def track_visibility(canonical: Gaussians, dynamic_index: torch.Tensor, camera: Camera, depth_tol: float = 0.05,
               min_alpha: float = 0.5, background=None, backend: str = "auto"
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(visible [D] bool, uv [D,2], depth [D]) of the dynamic Gaussians in ``camera``.

    A Gaussian is visible when its centre projects inside the image in front of the camera,
    the canonical render is opaque there (alpha >= min_alpha) and its depth is at most the
    rendered (alpha-normalised expected) depth times ``1 + depth_tol``.
    """
    with torch.no_grad():
        bg = None if background is None else torch.as_tensor(background, dtype=torch.float32,
                                                              device=canonical.device)
        _, alpha, meta = render_gaussians(canonical, camera, background=bg, backend=backend)
    alpha = alpha.detach().cpu().double().numpy()
    rdepth = meta["depth"].detach().cpu().double().numpy()
    pts = canonical.means.detach().cpu().double().numpy()[dynamic_index.cpu().numpy()]
    uv, z = camera.project(pts)  # float64 on the CPU, whatever device rendered
    H, W = camera.height, camera.width
    ok = np.isfinite(uv).all(1) & (z > 1e-6)
    ok &= (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)
    xi = np.clip(np.nan_to_num(uv[:, 0]).astype(np.int64), 0, W - 1)
    yi = np.clip(np.nan_to_num(uv[:, 1]).astype(np.int64), 0, H - 1)
    ok &= alpha[yi, xi] >= min_alpha
    ok &= z <= rdepth[yi, xi] * (1.0 + depth_tol)
    return ok, np.nan_to_num(uv), z


def observe_view(canonical: Gaussians, dynamic_index: torch.Tensor, camera: Camera, clip: np.ndarray,
                 preset: str = "medium", fb_threshold_px: float = 1.0, depth_tol: float = 0.05,
                 min_alpha: float = 0.5, background=None, backend: str = "auto") -> ViewObservation:
    """Tracks of one refined clip [T,H,W,3] at the dynamic Gaussians the view sees (see :class:`ViewObservation`)."""
    visible, uv, depth = track_visibility(canonical, dynamic_index, camera, depth_tol, min_alpha, background, backend)
    disp, valid = forward_tracks(np.asarray(clip, np.float32), preset, fb_threshold_px)
    d = sample_bilinear(disp, uv)                                  # [T,D,2]
    xi = np.clip(uv[:, 0].astype(np.int64), 0, camera.width - 1)
    yi = np.clip(uv[:, 1].astype(np.int64), 0, camera.height - 1)
    w = valid[:, yi, xi] & visible[None]                            # [T,D]
    pts = canonical.means.detach().cpu().double().numpy()[dynamic_index.cpu().numpy()]
    return ViewObservation(camera, visible, uv, d, w.astype(np.float64), projection_jacobians(pts, camera), depth)
