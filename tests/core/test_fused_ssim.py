"""Fused SSIM (anigs.ssim.fused, compiled kernel anigs.ssim.kernel) against the reference anigs.ssim.reference."""
from __future__ import annotations

import pytest
import torch

from anigs.ssim import kernel as ssim_kernel
from anigs.ssim import ssim
from anigs.ssim.fused import _FusedSSIMTorch, _planes, blur, fused_ssim

needs_kernel = pytest.mark.skipif(not ssim_kernel.available(), reason="the fused SSIM kernel does not build here")


def torch_path(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return _FusedSSIMTorch.apply(_planes(pred), _planes(target))


def pair(shape, seed: int = 0, noise: float = 0.1, dtype=torch.float32):
    """A target in [0,1] and a prediction near it (noise > 1: unrelated)."""
    g = torch.Generator().manual_seed(seed)
    y = torch.rand(shape, generator=g, dtype=torch.float64)
    x = (y + noise * torch.randn(shape, generator=g, dtype=torch.float64)).clamp(0, 1)
    return x.to(dtype), y.to(dtype)


def value_and_grad(fn, x: torch.Tensor, y: torch.Tensor):
    x = x.clone().requires_grad_(True)
    v = fn(x, y)
    v.backward()
    return v.detach(), x.grad


SHAPES = [(48, 64, 3), (2, 37, 53, 3), (5, 7, 1), (13, 17, 2), (1, 30, 11, 4)]


def test_blur_is_the_zero_padded_gaussian_filter():
    import torch.nn.functional as F

    from anigs.ssim.reference import _window

    x = torch.rand(3, 29, 41, dtype=torch.float64)
    ref = F.conv2d(x[None], _window(11, 1.5, 3, x.dtype, x.device), padding=5, groups=3)[0]
    assert torch.allclose(blur(x), ref, atol=1e-12)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("noise", [0.05, 2.0])
def test_values_and_gradients_match_the_reference(shape, noise):
    x, y = pair(shape, noise=noise)
    v_ref, g_ref = value_and_grad(ssim, x, y)
    scale = g_ref.abs().max()
    for fn in (fused_ssim, torch_path):
        v, g = value_and_grad(fn, x, y)
        assert v.shape == () and v.dtype == torch.float32
        assert abs(float(v) - float(v_ref)) < 1e-5, fn
        assert (g - g_ref).abs().max() <= 1e-4 * scale, fn


def test_identical_images_score_one_and_flat_ones_match_double_precision():
    x, _ = pair((24, 32, 3))
    assert float(fused_ssim(x, x)) == pytest.approx(1.0, abs=1e-6)
    # flat images: the variances come from the zero padding alone, where float32 cancels most;
    # the fused value stays within 5e-5 of the float64 reference (the float32 reference: 6.5e-5)
    c, d = torch.full((20, 20, 3), 0.25), torch.full((20, 20, 3), 0.75)
    truth = float(ssim(c.double(), d.double()))
    assert float(fused_ssim(c, d)) == pytest.approx(truth, abs=5e-5)
    assert float(torch_path(c, d)) == pytest.approx(truth, abs=5e-5)


def test_gradcheck_in_double_precision():
    x, y = pair((2, 6, 7, 2), dtype=torch.float64)  # smaller than the window: every border case
    x.requires_grad_(True)
    assert torch.autograd.gradcheck(lambda a: fused_ssim(a, y), (x,), eps=1e-6, atol=1e-8)
    # and the double-precision path equals the reference to rounding
    v_ref, g_ref = value_and_grad(ssim, x.detach(), y)
    v, g = value_and_grad(fused_ssim, x.detach(), y)
    assert abs(float(v) - float(v_ref)) < 1e-12
    assert torch.allclose(g, g_ref, rtol=1e-9, atol=1e-15)


@needs_kernel
def test_kernel_matches_the_torch_path_and_is_thread_count_independent():
    x, y = pair((3, 40, 57, 3), seed=3)
    v_t, g_t = value_and_grad(torch_path, x, y)
    n = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        v1, g1 = value_and_grad(ssim_kernel.ssim_cpu, x, y)
        torch.set_num_threads(2)
        v2, g2 = value_and_grad(ssim_kernel.ssim_cpu, x, y)
    finally:
        torch.set_num_threads(n)
    assert torch.equal(v1, v2) and torch.equal(g1, g2)  # bit-identical whatever the threads
    assert abs(float(v1) - float(v_t)) < 1e-6
    assert (g1 - g_t).abs().max() <= 1e-4 * g_t.abs().max()


@needs_kernel
def test_kernel_is_used_for_float32_cpu_and_repeatable():
    x, y = pair((30, 40, 3))
    a, ga = value_and_grad(fused_ssim, x, y)
    b, gb = value_and_grad(ssim_kernel.ssim_cpu, x, y)
    assert torch.equal(a, b) and torch.equal(ga, gb)
    c, gc = value_and_grad(fused_ssim, x, y)
    assert torch.equal(a, c) and torch.equal(ga, gc)


def test_no_grad_forward_and_upstream_gradient_scale():
    x, y = pair((16, 16, 3))
    with torch.no_grad():
        assert float(fused_ssim(x, y)) == pytest.approx(float(ssim(x, y)), abs=1e-5)
    xr = x.clone().requires_grad_(True)
    (3.0 * fused_ssim(xr, y)).backward()
    _, g = value_and_grad(fused_ssim, x, y)
    assert torch.allclose(xr.grad, 3 * g, rtol=1e-6, atol=0)


def test_target_with_grad_falls_back_to_the_reference_and_bad_shapes_raise():
    x, y = pair((12, 12, 3))
    yr = y.clone().requires_grad_(True)
    fused_ssim(x, yr).backward()
    assert yr.grad is not None
    with pytest.raises(ValueError, match="shapes differ"):
        fused_ssim(x, y[:-1])
    with pytest.raises(ValueError, match=r"\[H,W,C\]"):
        fused_ssim(x[..., 0], y[..., 0])
