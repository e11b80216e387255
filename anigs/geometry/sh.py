"""Real spherical harmonics up to degree 3 (the 3DGS basis and sign convention)."""
from __future__ import annotations

import torch

C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
      -0.4570457994644658, 1.445305721320277, -0.5900435899266435)


def eval_sh(degree: int, sh: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """Evaluate SH coefficients sh [N,C,3] (C >= (degree+1)^2) along unit dirs [N,3] -> [N,3].

    Returns the raw SH value; renderers add 0.5 and clamp at 0 to get colour.
    """
    if not 0 <= degree <= 3:
        raise ValueError(f"SH degree must be in 0..3, got {degree}")
    if sh.shape[1] < (degree + 1) ** 2:
        raise ValueError(f"sh has {sh.shape[1]} coefficients, degree {degree} needs {(degree + 1) ** 2}")
    out = C0 * sh[:, 0]
    if degree == 0:
        return out
    x, y, z = (d[:, None] for d in dirs.unbind(-1))
    out = out - C1 * y * sh[:, 1] + C1 * z * sh[:, 2] - C1 * x * sh[:, 3]
    if degree == 1:
        return out
    xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
    out = (out + C2[0] * xy * sh[:, 4] + C2[1] * yz * sh[:, 5] + C2[2] * (2 * zz - xx - yy) * sh[:, 6]
           + C2[3] * xz * sh[:, 7] + C2[4] * (xx - yy) * sh[:, 8])
    if degree == 2:
        return out
    return (out + C3[0] * y * (3 * xx - yy) * sh[:, 9] + C3[1] * xy * z * sh[:, 10]
            + C3[2] * y * (4 * zz - xx - yy) * sh[:, 11] + C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * sh[:, 12]
            + C3[4] * x * (4 * zz - xx - yy) * sh[:, 13] + C3[5] * z * (xx - yy) * sh[:, 14]
            + C3[6] * x * (xx - 3 * yy) * sh[:, 15])


def sh_colors(degree: int, sh: torch.Tensor, means: torch.Tensor, cam_center: torch.Tensor) -> torch.Tensor:
    """View-dependent colours [N,3] = max(SH(dir) + 0.5, 0), dir from camera to Gaussian."""
    if degree == 0:
        return torch.clamp_min(C0 * sh[:, 0] + 0.5, 0.0)
    dirs = torch.nn.functional.normalize(means - cam_center, dim=-1, eps=1e-12)
    return torch.clamp_min(eval_sh(degree, sh, dirs) + 0.5, 0.0)
