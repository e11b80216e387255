"""A similarity ``x -> s R x + t`` applied to a whole Gaussian set, SH colours included.

Means, rotations and scales follow from the covariance ``s^2 R Sigma R^T``. The colour of a
Gaussian seen along the unit direction ``d`` (camera to Gaussian) must be, after the transform, its
old colour along ``R^T d``: each SH band ``l`` (2l+1 coefficients) is mixed by one
(2l+1) x (2l+1) matrix, the Wigner D-matrix of ``R`` in the renderer's real basis. It is fitted
here, exactly, from the renderer's own basis functions (:func:`anigs.geometry.sh.eval_sh`) at
fixed directions, so the basis, its constants and its signs match the renderer by construction.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from anigs.gaussians import Gaussians
from anigs.geometry.basics import fibonacci_sphere
from anigs.geometry.quaternion import quat_from_matrix, quat_multiply
from anigs.geometry.sh import eval_sh

_FIT_DIRS = 64  # directions the band matrices are fitted at (>= 7 per band, well spread)
_SNAP = 1e-12  # band-matrix entries below this are rounding noise: set to zero (identity stays exact)


def check_rotation(R: np.ndarray, what: str = "R") -> np.ndarray:
    """``R`` as a float64 [3,3] proper rotation; ValueError for another shape, a non-orthogonal
    matrix or a reflection (det -1: a similarity must be proper)."""
    R = np.asarray(R, np.float64)
    if R.shape != (3, 3) or not np.isfinite(R).all():
        raise ValueError(f"{what}: expected a finite [3,3] rotation, got shape {R.shape}")
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > 1e-6:
        raise ValueError(f"{what}: not orthogonal (max |R^T R - I| = {err:.2e})")
    if np.linalg.det(R) < 0:
        raise ValueError(f"{what}: det R = -1, a reflection; a similarity must be a proper rotation (det +1)")
    return R


def _sh_basis(dirs: torch.Tensor) -> torch.Tensor:
    """The renderer's 16 real SH basis functions at unit ``dirs`` [M,3] -> [M,16] (float64)."""
    out = []
    for k in range(16):
        sh = torch.zeros(dirs.shape[0], 16, 3, dtype=torch.float64)
        sh[:, k] = 1.0
        out.append(eval_sh(3, sh, dirs)[:, 0])
    return torch.stack(out, 1)


def sh_band_matrices(R: np.ndarray, degree: int) -> list[np.ndarray]:
    """Per band l = 1..degree the [2l+1, 2l+1] matrix ``M_l`` with new = ``M_l @ old`` coefficients."""
    R = check_rotation(R)
    dirs = torch.from_numpy(fibonacci_sphere(_FIT_DIRS))
    old = _sh_basis(dirs).numpy()  # Y(d)
    back = _sh_basis(dirs @ torch.from_numpy(R)).numpy()  # Y(R^T d): rows are (R^T d)^T = d^T R
    mats = []
    for l in range(1, degree + 1):
        band = slice(l * l, (l + 1) * (l + 1))
        # Y_k(R^T d) = sum_j X_jk Y_j(d) (solved as Y(d) X = Y(R^T d)), so the new colour
        # sum_k c_k Y_k(R^T d) has the coefficients c'_j = sum_k X_jk c_k: M = X
        m = np.linalg.lstsq(old[:, band], back[:, band], rcond=None)[0]
        mats.append(np.where(np.abs(m) < _SNAP, 0.0, m))
    return mats


def rotate_sh(sh: torch.Tensor, R: np.ndarray) -> torch.Tensor:
    """SH colour coefficients ``sh`` [N,C,3] (C = (deg+1)^2, deg <= 3, the 3DGS basis of
    :mod:`anigs.geometry.sh`) of Gaussians rotated by the world rotation ``R`` [3,3]: the result seen
    along ``R d`` has the colour ``sh`` had along ``d``. Same dtype and device as ``sh``; float64 inside."""
    if sh.ndim != 3 or sh.shape[2] != 3:
        raise ValueError(f"rotate_sh: expected sh [N,C,3], got {tuple(sh.shape)}")
    degree = int(round(math.sqrt(sh.shape[1]))) - 1
    if (degree + 1) ** 2 != sh.shape[1] or not 0 <= degree <= 3:
        raise ValueError(f"rotate_sh: {sh.shape[1]} coefficients is not (deg+1)^2 for a degree in 0..3")
    out = sh.detach().to(torch.float64).clone()
    for l, m in enumerate(sh_band_matrices(R, degree), start=1):
        band = slice(l * l, (l + 1) * (l + 1))
        out[:, band] = torch.einsum("jk,nkc->njc", torch.from_numpy(m).to(out.device), out[:, band])
    return out.to(sh.dtype)


def transform_gaussians(g: Gaussians, scale: float, R: np.ndarray, t: np.ndarray) -> Gaussians:
    """``g`` moved by the similarity ``x -> scale * R @ x + t`` (``anigs.sfm.align.Similarity``):
    means [N,3] mapped, quaternions [N,4] (w,x,y,z) left-multiplied by R's (their norm kept),
    log-scales [N,3] + log(scale), opacities unchanged, SH [N,C,3] rotated (:func:`rotate_sh`).
    Float64 inside, float32 out, on ``g``'s device; extras are kept. ValueError for a reflection
    (det R = -1), a non-rotation R or a scale that is not finite and positive."""
    R = check_rotation(R)
    t = np.asarray(t, np.float64).reshape(-1)
    if t.shape != (3,) or not np.isfinite(t).all():
        raise ValueError(f"transform_gaussians: t must be a finite [3] vector, got shape {t.shape}")
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"transform_gaussians: scale must be finite and positive, got {scale}")
    dev, f64 = g.device, torch.float64
    Rt, tt = torch.from_numpy(R).to(dev), torch.from_numpy(t).to(dev)
    means = float(scale) * g.means.detach().to(f64) @ Rt.T + tt
    qR = torch.from_numpy(quat_from_matrix(R)[0]).to(dev)
    quats = quat_multiply(qR.expand(g.num, 4), g.quats.detach().to(f64))
    log_scales = g.log_scales.detach().to(f64) + math.log(scale)
    f32 = lambda x: x.to(torch.float32).contiguous()
    return Gaussians(f32(means), f32(quats), f32(log_scales), f32(g.opacity_logits.detach().clone()),
                     f32(rotate_sh(g.sh.detach().to(f64), R)), dict(g.extras))
