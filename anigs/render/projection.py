"""EWA projection of 3D Gaussians to screen space (differentiable, pure torch).

Shared by the ``torch`` and ``cpu`` backends, so they differ only in compositing.
Conventions: OpenCV camera (x right, y down, z forward), pixel centres at +0.5.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from anigs.geometry.quaternion import quat_to_rotmat

ALPHA_MIN = 1.0 / 255.0  # contributions below this are skipped
ALPHA_MAX = 0.99  # alpha clamp: one splat never makes a pixel fully opaque
T_MIN = 1e-4  # transmittance floor: stop compositing below this
EPS_2D = 0.3  # screen-space dilation of the 2D covariance (pixels^2)


def covariance_3d(quats: torch.Tensor, scales: torch.Tensor) -> torch.Tensor:
    """World-space covariances [N,3,3] = R S S^T R^T."""
    M = quat_to_rotmat(quats) * scales[..., None, :]
    return M @ M.transpose(-1, -2)


@dataclass
class Projected:
    """Screen-space Gaussians for all N inputs (culled ones have ``valid`` False).

    means2d [N,2] pixels; cov2d [N,2,2] dilated; conics [N,3] (a,b,c) of the inverse
    covariance; depths [N]; rects [N,4] int pixel boxes (x0,y0,x1,y1, half-open) of the
    region where alpha >= 1/255; radii [N] int; valid [N] bool.
    """

    means2d: torch.Tensor
    cov2d: torch.Tensor
    conics: torch.Tensor
    depths: torch.Tensor
    rects: torch.Tensor
    radii: torch.Tensor
    valid: torch.Tensor


def project_gaussians(
    means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
    viewmat: torch.Tensor, K: torch.Tensor, width: int, height: int,
    near: float = 0.01, far: float = 1e10, eps2d: float = EPS_2D,
) -> Projected:
    """Project Gaussians [N] with a pinhole camera (viewmat [4,4] world->camera, K [3,3])."""
    R, t = viewmat[:3, :3], viewmat[:3, 3]
    pc = means @ R.T + t  # [N,3]
    x, y, z = pc.unbind(-1)
    valid = (z > near) & (z < far)
    zs = torch.where(valid, z, torch.ones_like(z))  # safe divisor for culled splats
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    # Clamp the Jacobian's view direction to 1.3x the frustum (as 3DGS/gsplat) so
    # splats far outside the image do not blow up.
    tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
    lim_xp, lim_xn = (width - cx) / fx + 0.3 * tan_x, cx / fx + 0.3 * tan_x
    lim_yp, lim_yn = (height - cy) / fy + 0.3 * tan_y, cy / fy + 0.3 * tan_y
    tx = zs * torch.clamp(x / zs, min=-lim_xn, max=lim_xp)
    ty = zs * torch.clamp(y / zs, min=-lim_yn, max=lim_yp)
    zero = torch.zeros_like(zs)
    J = torch.stack([fx / zs, zero, -fx * tx / zs**2, zero, fy / zs, -fy * ty / zs**2], -1).reshape(-1, 2, 3)
    cov3 = covariance_3d(quats, scales)
    T = J @ R
    cov2 = T @ cov3 @ T.transpose(-1, -2)
    cov2 = cov2 + eps2d * torch.eye(2, dtype=cov2.dtype, device=cov2.device)
    a, b, c = cov2[:, 0, 0], cov2[:, 0, 1], cov2[:, 1, 1]
    det = a * c - b * b
    valid = valid & (det > 0) & torch.isfinite(det)
    det_s = torch.where(valid, det, torch.ones_like(det))
    conics = torch.stack([c / det_s, -b / det_s, a / det_s], -1)
    means2d = torch.stack([fx * x / zs + cx, fy * y / zs + cy], -1)
    valid = valid & torch.isfinite(means2d).all(-1) & torch.isfinite(conics).all(-1)
    valid = valid & (opacities >= ALPHA_MIN)

    with torch.no_grad():
        # Extent of the ellipse where opacity * exp(-0.5 d^T conic d) = 1/255.
        level = 2.0 * torch.log((opacities.detach() * 255.0).clamp_min(1.0))
        ex = torch.sqrt(level * a.detach().clamp_min(0)).nan_to_num(1e7, 1e7, 0).clamp_max(1e7)
        ey = torch.sqrt(level * c.detach().clamp_min(0)).nan_to_num(1e7, 1e7, 0).clamp_max(1e7)
        m2 = means2d.detach().nan_to_num(0, 0, 0).clamp(-1e7, 1e7)
        x0 = torch.ceil(m2[:, 0] - ex - 0.5).clamp(0, width)
        x1 = (torch.floor(m2[:, 0] + ex - 0.5) + 1).clamp(0, width)
        y0 = torch.ceil(m2[:, 1] - ey - 0.5).clamp(0, height)
        y1 = (torch.floor(m2[:, 1] + ey - 0.5) + 1).clamp(0, height)
        rects = torch.stack([x0, y0, x1, y1], -1).to(torch.int32)
        valid = valid & (rects[:, 2] > rects[:, 0]) & (rects[:, 3] > rects[:, 1])
        rects = torch.where(valid[:, None], rects, torch.zeros_like(rects))
        radii = torch.where(valid, torch.ceil(torch.maximum(ex, ey)), torch.zeros_like(ex)).to(torch.int32)
    return Projected(means2d, cov2, conics, z, rects, radii, valid)
