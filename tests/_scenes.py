"""Scenes shared by the tests and benchmarks: random Gaussians (rasterizer) and a ground with a
swaying shrub, its ring of cameras and a ground-truth sway (deformation, model update, baselines)."""
from __future__ import annotations

import math

import torch

from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask
from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians


def random_scene(n: int, width: int, height: int, sh_degree: int = 0, seed: int = 0, fov: float = 60.0,
                 dtype=torch.float32):
    """n Gaussians in a 2x2x2 cube 4 units in front of an identity camera.

    Returns (means, quats, scales, opacities, colors_or_sh, viewmat, K).
    """
    g = torch.Generator().manual_seed(seed)
    means = torch.rand(n, 3, generator=g) * 2 - 1
    means[:, 2] += 4
    quats = torch.randn(n, 4, generator=g)
    scales = torch.exp(torch.empty(n, 3).uniform_(math.log(0.01), math.log(0.05), generator=g))
    opac = torch.empty(n).uniform_(0.1, 0.9, generator=g)
    if sh_degree is None or sh_degree == 0:
        colors = torch.rand(n, 3, generator=g)
    else:
        colors = torch.randn(n, (sh_degree + 1) ** 2, 3, generator=g) * 0.3
    K = torch.tensor(intrinsics_from_fov(fov, width, height))
    out = (means, quats, scales, opac, colors, torch.eye(4, dtype=torch.float64), K)
    return tuple(t.to(dtype) for t in out)


# ---- an animated test scene: a static ground grid and a swaying shrub (deform, update, baselines)
def sway_scene(seed: int = 0, n_dyn: int = 200, grid: int = 15, anisotropic: bool = False):
    """A textured ground grid (static, z = 0) and a 'shrub': n_dyn Gaussians on a sphere of
    radius 0.4 centred 0.7 above the ground (dynamic). Returns (Gaussians, dynamic mask [N])."""
    g = torch.Generator().manual_seed(seed)
    i = torch.arange(n_dyn, dtype=torch.float64) + 0.5
    phi = torch.acos(1 - 2 * i / n_dyn)
    theta = math.pi * (1 + 5**0.5) * i
    shrub = torch.stack([torch.cos(theta) * torch.sin(phi), torch.sin(theta) * torch.sin(phi), torch.cos(phi)], 1)
    shrub = shrub.float() * 0.4
    shrub[:, 2] += 0.7
    xs = torch.linspace(-1.05, 1.05, grid)
    gx, gy = torch.meshgrid(xs, xs, indexing="ij")
    ground = torch.stack([gx.reshape(-1), gy.reshape(-1), torch.zeros(grid * grid)], 1)
    pts = torch.cat([ground, shrub])
    cols = torch.rand(pts.shape[0], 3, generator=g)
    scales = torch.cat([torch.full((grid * grid,), 0.07), torch.full((n_dyn,), 0.04)])
    G = Gaussians.from_points(pts, cols, scales, opacity=0.9)
    if anisotropic:
        G.log_scales[grid * grid:, 0] += 1.0
        G.quats = torch.randn(G.num, 4, generator=g)
    mask = torch.zeros(G.num, dtype=torch.bool)
    mask[grid * grid:] = True
    return G, mask


def ring_cameras(n: int = 4, w: int = 96, h: int = 72) -> list[Camera]:
    """n cameras on a ring around the shrub, looking slightly down."""
    cams = []
    for k in range(n):
        a = math.radians(20 + 360 * k / n)
        eye = (2.6 * math.cos(a), 2.6 * math.sin(a), 1.4)
        cams.append(Camera(intrinsics_from_fov(55, w, h), look_at(eye, (0, 0, 0.5)), w, h, f"v{k}"))
    return cams


def sway_motion(G, mask, T: int, K: int, amplitude: float) -> DCTDeformation:
    """Ground-truth wind sway: the shrub leans along x (DCT k=1) and y (k=2), proportionally to
    height, peak displacement ``amplitude`` at the top."""
    idx = dynamic_index_from_mask(mask)
    K = min(K, T - 1)
    gt = DCTDeformation(idx, T, K, rotation=False, num_gaussians=G.num)
    if K < 2:
        return gt  # too few frames for a sway
    h = G.means[idx, 2]
    amp = amplitude * h / h.max()
    b = gt.basis(torch.arange(T, dtype=torch.float64))
    with torch.no_grad():
        gt.pos_coeffs[:, 0, 0] = amp / b[:, 0].abs().max()
        gt.pos_coeffs[:, 1, 1] = 0.6 * amp / b[:, 1].abs().max()
    return gt
