"""Similarity transforms of reconstructions: Umeyama fit, z-up normalisation, pose errors.

A similarity maps old world points to new ones as ``x_new = s * R @ x_old + t``
(``s`` > 0 scalar, ``R`` [3,3] rotation, ``t`` [3]). Cameras follow the project convention
(:class:`anigs.cameras.Camera`, OpenCV, world-to-camera ``viewmat``).
"""
from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from anigs import geometry
from anigs.cameras import Camera
from anigs.geometry.similarity import Similarity

log = logging.getLogger(__name__)


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = True) -> Similarity:
    """Least-squares similarity with ``dst ≈ s R src + t`` (Umeyama 1991).

    Args:
        src, dst: corresponding points [N,3], N >= 3 and not all collinear.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3:
        raise ValueError(f"umeyama: need two [N,3] arrays of equal shape, got {src.shape} and {dst.shape}")
    if src.shape[0] < 3:
        raise ValueError(f"umeyama: need at least 3 correspondences, got {src.shape[0]}")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    var_s = (xs ** 2).sum() / len(src)
    if var_s < 1e-20:
        raise ValueError("umeyama: source points coincide")
    cov = xd.T @ xs / len(src)
    U, D, Vt = np.linalg.svd(cov)
    if D[1] < 1e-12 * max(D[0], 1e-300):
        raise ValueError("umeyama: points are collinear; the rotation is undetermined")
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    scale = float(np.trace(np.diag(D) @ S) / var_s) if with_scale else 1.0
    t = mu_d - scale * R @ mu_s
    return Similarity(scale, R, t)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation [3,3] taking direction ``a`` [3] onto direction ``b`` [3]."""
    a = np.asarray(a, dtype=np.float64) / np.linalg.norm(a)
    b = np.asarray(b, dtype=np.float64) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1 + 1e-12:  # opposite: rotate 180 degrees about any axis perpendicular to a
        axis = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def rotation_angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle in degrees of the relative rotation ``R = Ra Rb^T``, accurate at every angle.

    ``atan2(sin, cos)`` with ``sin`` the norm of R's skew-symmetric part and ``cos = (tr R - 1) / 2``:
    ``acos`` of the trace alone loses all precision near 0 (an error of 1e-16 in the trace is an
    angle of ~1e-6 degrees), and ``asin`` of the skew part near 180 degrees."""
    R = np.asarray(Ra, dtype=np.float64) @ np.asarray(Rb, dtype=np.float64).T
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
    return math.degrees(math.atan2(float(np.linalg.norm(skew)), float((np.trace(R) - 1) / 2)))


def pose_errors(est: Sequence[Camera], gt: Sequence[Camera]) -> dict:
    """Rotation and centre errors of cameras already in the ground-truth frame.

    Cameras are matched by ``name``. ``rotation_error_deg_after_best_rotation`` is the
    orientation error left after the single rotation that best aligns the orientations (it
    does not depend on how well the centres determine the alignment). The centre error is
    given in world units and as a percentage of the scene extent, defined here as the largest
    distance between two ground-truth camera centres (the capture's diameter).
    """
    by_name = {c.name: c for c in gt}
    missing = [c.name for c in est if c.name not in by_name]
    if missing:
        raise KeyError(f"pose_errors: no ground-truth camera named {missing[:5]} ({len(missing)} missing)")
    pairs = [(c, by_name[c.name]) for c in est]
    rot = np.array([rotation_angle_deg(e.R, g.R) for e, g in pairs])
    cen = np.array([np.linalg.norm(e.center - g.center) for e, g in pairs])
    gc = np.stack([g.center for g in gt])
    extent = float(np.max(np.linalg.norm(gc[:, None] - gc[None], axis=-1)))
    focal = np.array([abs(e.K[0, 0] * g.width / e.width - g.K[0, 0]) / g.K[0, 0] for e, g in pairs])
    pct = 100.0 * cen / max(extent, 1e-12)
    # orientation residual once the best global rotation is applied (independent of how
    # well the centres pin the alignment down: small-baseline captures)
    U, _, Vt = np.linalg.svd(sum(g.R.T @ e.R for e, g in pairs))
    Rbest = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    rot_best = np.array([rotation_angle_deg(e.R @ Rbest.T, g.R) for e, g in pairs])
    return {
        "num_cameras": len(pairs),
        "rotation_error_deg": {"mean": float(rot.mean()), "max": float(rot.max())},
        "rotation_error_deg_after_best_rotation": {"mean": float(rot_best.mean()), "max": float(rot_best.max())},
        "center_error": {"mean": float(cen.mean()), "max": float(cen.max())},
        "center_error_pct_extent": {"mean": float(pct.mean()), "max": float(pct.max())},
        "focal_error_pct": {"mean": float(100 * focal.mean()), "max": float(100 * focal.max())},
        "extent": extent,
        "extent_definition": "max distance between two ground-truth camera centres",
    }


# ---- z-up frame for reconstructions without ground truth ------------------------------------

def upright_similarity(cams: list[Camera], xyz: np.ndarray, ground_percentile: float,
                       camera_height: float | None = None) -> tuple[Similarity, dict]:
    """Rotation putting the estimated up on +z, camera centroid at x=y=0, ground at z=0.

    With ``camera_height`` the world is also scaled so the cameras' mean height above that
    ground equals it (e.g. 1.6 for photos taken at eye height in metres); otherwise, or when
    the cameras are not above the estimated ground, COLMAP's scale is kept.
    """
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    est = geometry.estimate_up(cams, xyz if len(xyz) >= 50 else None)
    up = est.up
    a, _ = geometry.roll_axes(cams)
    img_up = a[np.arange(len(cams)), np.asarray(est.rolls_deg, int) // 90] if est.rolls_deg else -np.stack(
        [c.R[1] for c in cams])
    tilt = np.degrees(np.arccos(np.clip(img_up @ up, -1, 1)))
    R = rotation_between(up, np.array([0.0, 0.0, 1.0]))
    centers = np.stack([c.center for c in cams]) @ R.T
    heights = (xyz @ R.T)[:, 2] if len(xyz) else centers[:, 2]
    ground_z = float(np.percentile(heights, ground_percentile))
    ground_mode = "percentile"
    if len(xyz) >= 10 and np.median(centers[:, 2]) <= ground_z:
        # cameras not above the low percentile (looking up at a building): the ground below them
        gr = geometry.estimate_ground(xyz @ R.T, np.array([0.0, 0.0, 1.0]), [
            Camera(c.K, np.c_[np.c_[c.R @ R.T, c.t].T, [0, 0, 0, 1]].T, c.width, c.height) for c in cams])
        ground_z, ground_mode = gr.offset, f"ground-{gr.method}"
        log.warning("upright frame: the cameras are not above the %g-th percentile of the point heights; "
                    "ground from %s", ground_percentile, gr.method)
    t = np.array([-centers[:, 0].mean(), -centers[:, 1].mean(), -ground_z])
    mean_height = float((centers[:, 2] + t[2]).mean())
    extent = float(np.ptp(centers, axis=0).max()) if len(cams) > 1 else 0.0
    scale = 1.0
    if camera_height is not None:
        if mean_height > 1e-3 * max(extent, 1e-12):
            scale = camera_height / mean_height
        else:
            log.warning("cameras are not above the estimated ground (mean height %.3g): keeping COLMAP's scale",
                        mean_height)
    return Similarity(scale, R, scale * t), {"mode": "upright", "up_in_colmap_frame": up,
                                   "up_estimate": est.to_dict(), "ground": ground_mode,
                                   "mean_camera_height_before_scaling": mean_height,
                                   "camera_tilt_from_up_deg": {"mean": float(tilt.mean()),
                                                               "max": float(tilt.max())}}


def align_cameras(src: Sequence[Camera], dst: Sequence[Camera]) -> tuple[Similarity, float]:
    """Similarity src-frame -> dst-frame from cameras matched by name; also the RMS centre error (dst units)."""
    by_name = {c.name: c for c in dst}
    pairs = [(c, by_name[c.name]) for c in src if c.name in by_name]
    if len(pairs) < 3:
        raise ValueError(f"align_cameras: only {len(pairs)} camera names in common (need >= 3); "
                         f"e.g. {[c.name for c in src[:3]]} vs {[c.name for c in dst[:3]]}")
    a = np.stack([p[0].center for p in pairs])
    b = np.stack([p[1].center for p in pairs])
    sim = umeyama(a, b)
    rms = float(np.sqrt(((sim.apply(a) - b) ** 2).sum(1).mean()))
    return sim, rms
