"""The gsplat backend's meta contract, on the CPU with a stand-in ``gsplat`` module.

gsplat's rasterizer consumes a batched means2d [C,N,2]; ``meta["means2d"]`` is its row 0
([N,2]) and must behave like the other backends' for densification: ``retain_grad()``
before backward, then ``.grad`` holds the screen-space gradient.
"""
from __future__ import annotations

import sys
import types

import pytest
import torch

from anigs.static.densify import DensifyState, update_state
from anigs.render import gsplat_backend

W, H = 24, 16


def _fake_rasterization(captured: dict):
    """A differentiable toy with gsplat's signature and output layout (one camera)."""

    def rasterization(means, quats, scales, opacities, colors, viewmats, Ks, width, height, **kw):
        K = Ks[0]
        means2d = torch.stack([K[0, 0] * means[:, 0] / means[:, 2] + K[0, 2],
                               K[1, 1] * means[:, 1] / means[:, 2] + K[1, 2]], -1)[None]  # [1,N,2]
        means2d.retain_grad()  # the reference gradient
        captured["means2d"] = means2d
        ys, xs = torch.meshgrid(torch.arange(height) + 0.5, torch.arange(width) + 0.5, indexing="ij")
        d2 = (xs[..., None] - means2d[0, :, 0]) ** 2 + (ys[..., None] - means2d[0, :, 1]) ** 2  # [H,W,N]
        wgt = opacities * torch.exp(-d2 / (2 * (scales[:, 0] * K[0, 0]) ** 2))
        alpha = 1 - torch.exp(-wgt.sum(-1))
        rgb = torch.einsum("hwn,nc->hwc", wgt, colors) / (1 + wgt.sum(-1, keepdim=True))
        depth = (wgt * means[:, 2]).sum(-1, keepdim=True)
        out = torch.cat([rgb, depth], -1)[None]
        radii = torch.full((1, means.shape[0]), 3, dtype=torch.int32)
        return out, alpha[None, ..., None], {"radii": radii, "means2d": means2d}

    return rasterization


@pytest.fixture
def fake_gsplat(monkeypatch):
    captured: dict = {}
    monkeypatch.setitem(sys.modules, "gsplat", types.SimpleNamespace(rasterization=_fake_rasterization(captured)))
    return captured


def _scene(n: int = 5):
    g = torch.Generator().manual_seed(0)
    means = torch.cat([torch.rand(n, 2, generator=g) - 0.5, 2 + torch.rand(n, 1, generator=g)], 1)
    leaves = [means, torch.randn(n, 4, generator=g), torch.full((n, 3), 0.1),
              torch.rand(n, generator=g) * 0.5 + 0.3, torch.rand(n, 3, generator=g)]
    K = torch.tensor([[20.0, 0, W / 2], [0, 20.0, H / 2], [0, 0, 1]])
    return [t.requires_grad_(True) for t in leaves], torch.eye(4), K


def _render(leaves, viewmat, K):
    return gsplat_backend._render(*leaves, viewmat, K, W, H, None, torch.zeros(3), 0.01, 1e10)


def test_means2d_retain_grad_receives_the_gradient(fake_gsplat):
    leaves, viewmat, K = _scene()
    rgb, alpha, meta = _render(leaves, viewmat, K)
    m2d = meta["means2d"]
    assert m2d.shape == (5, 2)
    m2d.retain_grad()
    (rgb.square().sum() + alpha.sum()).backward()
    assert m2d.grad is not None and m2d.grad.shape == (5, 2)
    assert m2d.grad.abs().sum() > 0
    torch.testing.assert_close(m2d.grad, fake_gsplat["means2d"].grad[0])


def test_means2d_also_used_in_the_loss(fake_gsplat):
    """A loss term on means2d itself adds to its gradient exactly once."""
    leaves, viewmat, K = _scene()
    rgb, _, meta = _render(leaves, viewmat, K)
    m2d = meta["means2d"]
    m2d.retain_grad()
    (rgb.sum() + 0.5 * m2d.square().sum()).backward()
    torch.testing.assert_close(m2d.grad, fake_gsplat["means2d"].grad[0])


def test_densify_update_state_reads_the_gradient(fake_gsplat):
    leaves, viewmat, K = _scene()
    rgb, _, meta = _render(leaves, viewmat, K)
    meta["means2d"].retain_grad()
    rgb.sum().backward()
    state = DensifyState.empty(5)
    update_state(state, meta, W, H)
    assert (state.count == 1).all() and (state.grad_sum > 0).all()


def test_without_retain_grad_densify_asks_for_it(fake_gsplat):
    leaves, viewmat, K = _scene()
    rgb, _, meta = _render(leaves, viewmat, K)
    rgb.sum().backward()
    with pytest.raises(RuntimeError, match="retain_grad"):
        update_state(DensifyState.empty(5), meta, W, H)


def test_render_refuses_cpu_tensors():
    leaves, viewmat, K = _scene()
    with pytest.raises(ValueError, match="CUDA"):
        gsplat_backend.render(*leaves, viewmat, K, W, H, None, torch.zeros(3), 0.01, 1e10)
