"""Numerically hard inputs: outputs and gradients must stay finite on every backend."""
from __future__ import annotations

import pytest
import torch

from anigs.cameras import intrinsics_from_fov
from anigs.render import rasterize

BACKENDS = ["cpu", "torch"]
W, H = 32, 24
BG = torch.tensor([0.2, 0.4, 0.6])


def _K(w=W, h=H):
    return torch.tensor(intrinsics_from_fov(60, w, h), dtype=torch.float32)


def _one(n=1, z=4.0, scale=0.3, opacity=0.8):
    means = torch.zeros(n, 3)
    means[:, 2] = z
    quats = torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1)
    scales = torch.full((n, 3), scale)
    opac = torch.full((n,), opacity)
    colors = torch.rand(n, 3, generator=torch.Generator().manual_seed(n))
    return means, quats, scales, opac, colors


def _run(params, backend, w=W, h=H):
    leaves = [p.clone().requires_grad_(True) for p in params]
    rgb, alpha, meta = rasterize(*leaves, torch.eye(4), _K(w, h), w, h, background=BG, backend=backend)
    (rgb.sum() + alpha.sum() + meta["depth"].sum()).backward()
    assert torch.isfinite(rgb).all() and torch.isfinite(alpha).all() and torch.isfinite(meta["depth"]).all()
    for p in leaves:
        assert p.grad is not None and torch.isfinite(p.grad).all()
    return rgb.detach(), alpha.detach(), meta, [p.grad for p in leaves]


def _is_background(rgb, alpha):
    return torch.equal(alpha, torch.zeros_like(alpha)) and torch.allclose(rgb, BG.expand_as(rgb))


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_gaussians(backend):
    rgb, alpha, meta, _ = _run([p[:0] for p in _one()], backend)
    assert _is_background(rgb, alpha)
    assert meta["radii"].shape == (0,)


@pytest.mark.parametrize("backend", BACKENDS)
def test_one_gaussian(backend):
    rgb, alpha, meta, grads = _run(_one(), backend)
    assert alpha.max() > 0.5 and meta["radii"][0] > 0
    assert grads[0].abs().sum() > 0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("z", [-2.0, 0.0, 0.01])
def test_behind_camera_and_at_near_plane(backend, z):
    rgb, alpha, meta, _ = _run(_one(z=z), backend)
    assert _is_background(rgb, alpha)
    assert meta["radii"][0] == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_just_past_near_plane_is_finite(backend):
    _run(_one(z=0.0101, scale=0.001), backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scale", [1e-8, 1e4])
def test_extreme_scales(backend, scale):
    rgb, alpha, _, _ = _run(_one(n=3, scale=scale), backend)
    if scale == 1e4:  # covers the whole image, faintly (the density is spread out)
        assert alpha.min() > 0
    else:  # a point: drawn through the 0.3 px^2 dilation only; footprint radius
        # sqrt(2 ln(255 * 0.8) * 0.3) = 1.8 px, so at most 4x4 pixels
        assert 0 < (alpha > 0).sum() <= 16


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_quaternion_is_identity_with_finite_gradient(backend):
    base = list(_one(n=1, scale=0.3))
    base[2] = torch.tensor([[0.5, 0.2, 0.1]])  # anisotropic so rotation matters
    ident = _run(base, backend)[0]
    zero = list(base)
    zero[1] = torch.zeros(1, 4)
    rgb, _, _, grads = _run(zero, backend)
    assert torch.allclose(rgb, ident, atol=1e-6)
    assert torch.isfinite(grads[1]).all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_thousand_stacked_opaque_splats(backend):
    params = _one(n=1000, scale=0.5, opacity=1.0)
    rgb, alpha, _, _ = _run(params, backend)
    assert alpha.max() < 1.0, "alpha must stay below 1 (transmittance floor)"
    assert 1 - alpha.max() >= 1e-4 * 0.99
    assert alpha.max() > 0.99


@pytest.mark.parametrize("backend", BACKENDS)
def test_gaussian_straddling_border(backend):
    means, quats, scales, opac, colors = _one()
    K = _K()
    means[0, 0] = -K[0, 2] / K[0, 0] * 4.0  # projects onto the left edge x=0
    rgb, alpha, meta, grads = _run([means, quats, scales, opac, colors], backend)
    assert alpha[:, 0].max() > 0.3 and alpha[:, -1].max() == 0
    assert grads[0][0, 0].abs() > 0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("w,h", [(1, 24), (32, 1), (1, 1)])
def test_one_pixel_wide_or_high(backend, w, h):
    rgb, alpha, _, _ = _run(_one(n=5), backend, w, h)
    assert rgb.shape == (h, w, 3) and alpha.max() > 0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("which", [0, 1, 2, 3, 4])
def test_nan_input_is_a_clear_error(backend, which):
    params = list(_one(n=4))
    params[which] = params[which].clone()
    params[which].view(-1)[0] = float("nan")
    name = ["means", "quats", "scales", "opacities", "colors"][which]
    with pytest.raises(ValueError, match=name):
        rasterize(*params, torch.eye(4), _K(), W, H, backend=backend)


def test_bad_shapes_and_sizes_are_clear_errors():
    p = _one(n=2)
    with pytest.raises(ValueError, match="shape"):
        rasterize(p[0], p[1][:1], *p[2:], torch.eye(4), _K(), W, H)
    with pytest.raises(ValueError, match="image size"):
        rasterize(*p, torch.eye(4), _K(), 0, H)
    with pytest.raises(ValueError, match="backend"):
        rasterize(*p, torch.eye(4), _K(), W, H, backend="vulkan")
