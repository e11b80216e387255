"""Tile culling of the cpu kernel (``csrc/cull.cpp``): thin, tilted splats bin only the tiles (and
composite only the rows and columns of each tile) that their ellipse reaches, and draw exactly what
the pure-torch reference draws from their whole pixel boxes."""
from __future__ import annotations

import math

import pytest
import torch

from anigs.cameras import intrinsics_from_fov
from anigs.render import rasterize
from anigs.render.cpu_backend import tile_pairs

W, H = 256, 192


def _needles(n: int, seed: int, ratio: float = 60.0):
    """n needles (one long axis ``ratio`` times the others) in every in-plane direction, some tilted
    towards the camera, opacities from just above 1/255 to 1, 4 units in front of the camera."""
    g = torch.Generator().manual_seed(seed)
    means = torch.rand(n, 3, generator=g) * torch.tensor([3.0, 2.2, 1.0]) - torch.tensor([1.5, 1.1, 0.5])
    means[:, 2] += 4
    angle = torch.rand(n, generator=g) * math.pi  # rotation about the view axis
    tilt = (torch.rand(n, generator=g) - 0.5) * 1.2  # and about x
    half = 0.5 * angle
    qz = torch.stack([torch.cos(half), torch.zeros(n), torch.zeros(n), torch.sin(half)], 1)
    qx = torch.stack([torch.cos(0.5 * tilt), torch.sin(0.5 * tilt), torch.zeros(n), torch.zeros(n)], 1)
    w1, x1, y1, z1 = qz.unbind(1)
    w2, x2, y2, z2 = qx.unbind(1)
    quats = torch.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], 1)
    thin = torch.exp(torch.empty(n).uniform_(math.log(0.002), math.log(0.01), generator=g))
    scales = torch.stack([thin * ratio, thin, thin], 1)
    opac = torch.exp(torch.empty(n).uniform_(math.log(1.02 / 255), 0.0, generator=g)).clamp_max(1.0)
    colors = torch.rand(n, 3, generator=g)
    K = torch.tensor(intrinsics_from_fov(60, W, H), dtype=torch.float32)
    return means, quats, scales, opac, colors, torch.eye(4), K


def _render(scene, backend):
    means, quats, scales, opac, colors, viewmat, K = scene
    leaves = [t.clone().requires_grad_(True) for t in (means, quats, scales, opac, colors)]
    rgb, alpha, meta = rasterize(*leaves, viewmat, K, W, H, background=torch.tensor([0.1, 0.5, 0.9]), backend=backend)
    g = torch.Generator().manual_seed(5)
    ((rgb * torch.randn(H, W, 3, generator=g)).sum() + (alpha * torch.randn(H, W, generator=g)).sum()).backward()
    return rgb.detach(), alpha.detach(), [t.grad for t in leaves]


@pytest.mark.parametrize("seed", [0, 1])
def test_needles_draw_what_the_reference_draws(seed):
    scene = _needles(300, seed)
    culled, boxed = tile_pairs(*scene[:4], scene[5], scene[6], W, H)
    assert culled < 0.7 * boxed, f"the culling should drop the tiles thin tilted needles miss: {culled} of {boxed}"
    r_t, a_t, g_t = _render(scene, "torch")
    r_c, a_c, g_c = _render(scene, "cpu")
    # one culled pixel that the reference draws costs at least 1/255 of alpha there
    assert (a_t - a_c).abs().max() <= 1e-4 and (r_t - r_c).abs().max() <= 1e-4
    assert (a_t > 1 / 255).float().mean() > 0.2, "the needles must cover the image"
    for name, gt, gc in zip(["means", "quats", "scales", "opacities", "colors"], g_t, g_c):
        rel = (gt - gc).norm() / gt.norm()
        assert rel <= 1e-3, (name, float(rel))


def test_culling_is_deterministic_across_thread_counts():
    scene = _needles(300, 2)
    old = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        a = _render(scene, "cpu")
        torch.set_num_threads(max(2, old))
        b = _render(scene, "cpu")
    finally:
        torch.set_num_threads(old)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert all(torch.equal(x, y) for x, y in zip(a[2], b[2]))

