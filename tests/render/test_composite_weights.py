"""Forward-only blend weights of the cpu kernel (``anigs_composite_weights``,
:func:`anigs.render.cpu_backend.composite_weights_cpu`) and their use in
:func:`anigs.masks.visibility.blend_weights`.

The reference is one backward pass of the cpu rasterizer with zero colours: d(sum_p rgb_c(p)
f_c(p)) / d colour_ic = sum_p w_i(p) f_c(p), with w_i(p) = alpha_i(p) T_i(p). A second, independent
check is the forward image itself: sum_i w_i(p) = alpha(p) at every pixel.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians
from anigs.render import visibility
from anigs.render import rasterize
from anigs.render.cpu_backend import composite_weights_cpu
from tests._scenes import random_scene

ROOT = Path(__file__).resolve().parents[2]
SIZES = [(64, 48), (70, 45)]  # a multiple of the 16x16 tiles, and one that is not
EYES = [(0.0, 0.0, 0.0), (1.2, 0.6, 0.3), (-1.5, -0.8, 1.0), (0.3, -1.4, 6.5)]  # the last looks back at the cube


def _camera(eye, W, H):
    """viewmat [4,4] float32 looking from ``eye`` at the random scene's cube (centred at z = 4), K [3,3]."""
    target = (0.0, 0.0, 4.0)
    if eye == (0.0, 0.0, 0.0):
        vm = np.eye(4)
    else:
        vm = look_at(eye, target, up=(0.0, -1.0, 0.0))
    return torch.tensor(vm, dtype=torch.float32), torch.tensor(intrinsics_from_fov(60, W, H), dtype=torch.float32)


def _factors(H, W, C, seed, binary=False):
    g = torch.Generator().manual_seed(seed)
    f = torch.rand(H, W, C, generator=g)
    return (f >= 0.5).float() if binary else f


def _reference(means, quats, scales, opac, viewmat, K, W, H, factors):
    """[N, C] weight sums from one backward pass of the cpu rasterizer (float32, as float64)."""
    colors = torch.zeros(means.shape[0], 3, requires_grad=True)
    rgb, _, _ = rasterize(means, quats, scales, opac, colors, viewmat, K, W, H, backend="cpu")
    gout = torch.zeros(H, W, 3)
    gout[..., : factors.shape[2]] = factors
    rgb.backward(gout)
    return colors.grad[:, : factors.shape[2]].double()


def _alpha(means, quats, scales, opac, viewmat, K, W, H):
    with torch.no_grad():
        _, alpha, _ = rasterize(means, quats, scales, opac, torch.zeros(means.shape[0], 3), viewmat, K, W, H,
                                backend="cpu")
    return alpha.double()


def _check(w, ref, scene, viewmat, K, W, H, factors):
    """The new weights against the backward reference and against the forward's alpha."""
    assert w.dtype == torch.float64 and w.shape == ref.shape
    torch.testing.assert_close(w, ref, rtol=1e-5, atol=1e-6)
    # sum_i w_i(p) = alpha(p): the weights are those of the image the forward renders
    alpha = _alpha(*scene[:4], viewmat, K, W, H)
    expect = (alpha[..., None] * factors.double()).sum((0, 1))
    torch.testing.assert_close(w.sum(0), expect, rtol=1e-5, atol=1e-4)


@pytest.fixture(autouse=True)
def _one_thread():
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


@pytest.mark.parametrize("W,H", SIZES)
@pytest.mark.parametrize("C", [1, 2, 3])
def test_matches_backward_reference(W, H, C):
    scene = random_scene(300, W, H, 0, seed=10 + C)
    for k, eye in enumerate(EYES):
        viewmat, K = _camera(eye, W, H)
        for binary in (False, True):
            f = _factors(H, W, C, seed=100 * C + k, binary=binary)
            w = composite_weights_cpu(*scene[:4], viewmat, K, W, H, f)
            ref = _reference(*scene[:4], viewmat, K, W, H, f)
            assert (ref[:, 0] > 0).sum() > 50, "the camera should see the scene"
            _check(w, ref, scene, viewmat, K, W, H, f)


def test_factor_layouts():
    """[H,W] factors are one channel; numpy and non-contiguous factors give the same result."""
    W, H = 70, 45
    scene = random_scene(300, W, H, 0, seed=5)
    viewmat, K = _camera(EYES[1], W, H)
    f = _factors(H, W, 3, seed=6)
    w = composite_weights_cpu(*scene[:4], viewmat, K, W, H, f)
    assert torch.equal(composite_weights_cpu(*scene[:4], viewmat, K, W, H, f[..., 1]), w[:, 1:2])
    assert torch.equal(composite_weights_cpu(*scene[:4], viewmat, K, W, H, f.numpy()), w)
    ft = f.permute(2, 0, 1).contiguous().permute(1, 2, 0)  # same values, channel-planar strides
    assert not ft.is_contiguous()
    assert torch.equal(composite_weights_cpu(*scene[:4], viewmat, K, W, H, ft), w)
    for bad in (torch.ones(H, W, 4), torch.ones(H + 1, W, 1), torch.ones(W, H, 1), torch.ones(H, W, 0)):
        with pytest.raises(ValueError, match="factors"):
            composite_weights_cpu(*scene[:4], viewmat, K, W, H, bad)


def _one_then_two_threads(args: tuple, repeats: int = 1) -> list[torch.Tensor]:
    """``composite_weights_cpu(*args)`` with 1 torch thread, then ``repeats`` times with 2; leaves 1 thread."""
    torch.set_num_threads(1)
    out = [composite_weights_cpu(*args)]
    torch.set_num_threads(2)
    out += [composite_weights_cpu(*args) for _ in range(repeats)]
    torch.set_num_threads(1)
    return out


@pytest.mark.parametrize("W,H", SIZES)
def test_thread_count_gives_identical_bits(W, H):
    """Pair sums reduced per splat in a fixed order: 1 and 2 threads agree bit for bit (also with
    several binning chunks: 3000 splats)."""
    scene = random_scene(3000, W, H, 0, seed=21)
    f = _factors(H, W, 3, seed=22)
    for eye in EYES[:2]:
        viewmat, K = _camera(eye, W, H)
        w1, w2, w2b = _one_then_two_threads((*scene[:4], viewmat, K, W, H, f), repeats=2)
        assert torch.equal(w1, w2) and torch.equal(w2, w2b)
        _check(w1, _reference(*scene[:4], viewmat, K, W, H, f), scene, viewmat, K, W, H, f)


def test_culled_gaussians_get_zero():
    """Behind the camera, outside the image, below the alpha cutoff, or hidden behind an opaque
    layer (never composited: early termination): exactly 0; the rest of the scene unchanged."""
    W, H = 70, 45
    means, quats, scales, opac, _, viewmat, K = random_scene(300, W, H, 0, seed=31)
    n = means.shape[0]
    extra_means = torch.tensor([[0.0, 0.0, -4.0],    # behind the camera
                                [0.0, 0.0, 0.005],   # in front of the near plane
                                [40.0, 0.0, 4.0],    # outside the image (right)
                                [0.0, -30.0, 4.0],   # outside the image (top)
                                [0.1, 0.1, 4.0]])    # in view but opacity < 1/255
    m = torch.cat([means, extra_means])
    q = torch.cat([quats, torch.tensor([[1.0, 0, 0, 0]]).repeat(5, 1)])
    s = torch.cat([scales, torch.full((5, 3), 0.05)])
    o = torch.cat([opac, torch.tensor([0.9, 0.9, 0.9, 0.9, 0.003])])
    f = _factors(H, W, 2, seed=32)
    w = composite_weights_cpu(m, q, s, o, viewmat, K, W, H, f)
    assert torch.equal(w[n:], torch.zeros(5, 2))
    torch.testing.assert_close(w[:n], composite_weights_cpu(means, quats, scales, opac, viewmat, K, W, H, f),
                               rtol=0, atol=0)

    # a probe behind an opaque wall: the forward stops before it reaches the probe
    ys, xs = torch.meshgrid(torch.linspace(-2, 2, 30), torch.linspace(-2.5, 2.5, 36), indexing="ij")
    wall = torch.stack([xs.reshape(-1), ys.reshape(-1), torch.full((xs.numel(),), 3.0)], 1)
    probe = torch.tensor([[0.0, 0.0, 6.0], [0.0, 0.0, 1.0]])  # behind the wall, in front of it
    pts = torch.cat([wall, probe])
    nw = len(wall)
    q = torch.tensor([[1.0, 0, 0, 0]]).repeat(len(pts), 1)
    s = torch.cat([torch.full((nw, 3), 0.12), torch.full((2, 3), 0.2)])
    o = torch.full((len(pts),), 0.999)
    f = torch.ones(H, W, 1)
    w = composite_weights_cpu(pts, q, s, o, viewmat, K, W, H, f)
    assert w[nw, 0] == 0.0 and w[nw + 1, 0] > 10.0
    _check(w, _reference(pts, q, s, o, viewmat, K, W, H, f), (pts, q, s, o), viewmat, K, W, H, f)


def test_empty_scene():
    W, H = 64, 48
    viewmat, K = _camera(EYES[0], W, H)
    e3, e4 = torch.zeros(0, 3), torch.zeros(0, 4)
    for C in (1, 3):
        w = composite_weights_cpu(e3, e4, e3, torch.zeros(0), viewmat, K, W, H, torch.ones(H, W, C))
        assert w.shape == (0, C) and w.dtype == torch.float64
    # Gaussians, none drawn (all behind the camera)
    means, quats, scales, opac, *_ = random_scene(50, W, H, 0, seed=41)
    w = composite_weights_cpu(-means, quats, scales, opac, viewmat, K, W, H, torch.ones(H, W, 2))
    assert torch.equal(w, torch.zeros(50, 2))


@pytest.mark.parametrize("W,H", SIZES)
def test_near_opaque_early_termination(W, H):
    """Opacity near 1 (alpha clamped at 0.99) and many layers: pixels stop at the transmittance floor."""
    means, quats, scales, _, _, viewmat, K = random_scene(600, W, H, 0, seed=51)
    scales = scales * 6
    opac = torch.full((600,), 0.999)
    scene = (means, quats, scales, opac)
    alpha = _alpha(*scene, viewmat, K, W, H)
    assert float(alpha.max()) > 1 - 2e-4  # the floor was reached
    for C in (1, 3):
        f = _factors(H, W, C, seed=52)
        w = composite_weights_cpu(*scene, viewmat, K, W, H, f)
        _check(w, _reference(*scene, viewmat, K, W, H, f), scene, viewmat, K, W, H, f)
        # most splats are hidden behind the first layers: never composited, weight 0
        assert (w[:, 0] == 0).sum() > 100


def test_invalid_inputs_raise():
    W, H = 16, 12
    means, quats, scales, opac, _, viewmat, K = (t.clone() for t in random_scene(10, W, H, 0, seed=61))
    f = torch.ones(H, W, 1)
    scales[3, 1] = -0.1
    with pytest.raises(ValueError, match="scales"):
        composite_weights_cpu(means, quats, scales, opac, viewmat, K, W, H, f)
    scales[3, 1] = 0.1
    means[2, 0] = float("nan")
    with pytest.raises(ValueError, match="means"):
        composite_weights_cpu(means, quats, scales, opac, viewmat, K, W, H, f)


# ---- anigs.masks.visibility.blend_weights: the forward-only path and the backward fallback

def _lift_scene(W, H):
    means, quats, scales, opac, colors, *_ = random_scene(400, W, H, 0, seed=71)
    sh = torch.zeros(len(means), 1, 3)
    g = Gaussians(means, quats, scales.log(), torch.logit(opac), sh)
    cams = []
    for k, eye in enumerate(EYES[:3]):
        viewmat, K = _camera(eye, W, H)
        cams.append(Camera(K.double().numpy(), viewmat.double().numpy(), W, H, f"c{k}"))
    return g, cams


@pytest.mark.parametrize("W,H", SIZES)
def test_blend_weights_forward_matches_backward(W, H):
    g, cams = _lift_scene(W, H)
    assert visibility._blend_backend() == "cpu"
    for k, cam in enumerate(cams):
        mask = _factors(H, W, 1, seed=80 + k, binary=True)[..., 0].bool().numpy()
        total, inside = visibility.blend_weights(g, cam, mask)
        rt, ri = visibility.blend_weights_backward(g, cam, mask)
        assert total.dtype == np.float64 and total.shape == (g.num,) and inside.shape == (g.num,)
        assert (total > 0).sum() > 50 and (inside > 0).sum() > 20
        np.testing.assert_allclose(total, rt, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(inside, ri, rtol=1e-5, atol=1e-6)
        assert np.all(inside <= total + 1e-9)
        t0, i0 = visibility.blend_weights(g, cam)
        np.testing.assert_array_equal(t0, total)
        assert not i0.any()


def test_blend_weights_of_two_masks_in_one_pass_are_those_of_each_alone():
    W, H = 70, 45
    g, cams = _lift_scene(W, H)
    cam = cams[0]
    masks = _factors(H, W, 2, seed=95, binary=True).bool().numpy()
    for fn, exact in ((visibility.blend_weights, True), (visibility.blend_weights_backward, False)):
        total, inside = fn(g, cam, masks)
        assert inside.shape == (g.num, 2) and (inside > 0).sum() > 20
        for k in range(2):
            t, i = fn(g, cam, masks[..., k])
            np.testing.assert_array_equal(t, total)
            if exact:  # the cpu kernel sums each channel on its own: the same bits
                np.testing.assert_array_equal(i, inside[:, k])
            else:  # the backward pass's float32 reductions round differently
                np.testing.assert_allclose(i, inside[:, k], rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="at most 2 masks"):
        visibility.blend_weights(g, cam, np.ones((H, W, 3), bool))


def test_blend_weights_fallback_backend(monkeypatch):
    """Without the cpu kernel, blend_weights takes the backward pass of the backend in use."""
    W, H = 70, 45
    g, cams = _lift_scene(W, H)
    cam = cams[1]
    mask = _factors(H, W, 1, seed=91, binary=True)[..., 0].bool().numpy()
    fast = visibility.blend_weights(g, cam, mask)
    calls = []
    real = visibility.blend_weights_backward

    def spy(*args):
        calls.append(args[-1])
        return real(*args)

    monkeypatch.setattr(visibility, "_blend_backend", lambda: "torch")
    monkeypatch.setattr(visibility, "blend_weights_backward", spy)
    slow = visibility.blend_weights(g, cam, mask)
    assert calls == ["torch"]
    for a, b in zip(fast, slow):
        assert (b > 0).sum() > 50
        np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-3)


def test_blend_weights_nothing_in_view():
    g, cams = _lift_scene(64, 48)
    cam = Camera(cams[0].K, look_at((0.0, 0.0, 0.0), (0.0, 0.0, -4.0), up=(0.0, -1.0, 0.0)), 64, 48, "away")
    total, inside = visibility.blend_weights(g, cam, np.ones((48, 64), bool))
    assert total.shape == (g.num,) and not total.any() and not inside.any()


@pytest.mark.parametrize("env", [{"ANIGS_KERNEL_THREADS": "pool"}, {"ANIGS_KERNEL_ARCH": "none"}],
                         ids=["thread-pool", "baseline-isa"])
def test_other_kernel_builds(tmp_path, env):
    """The kernel's own thread pool (instead of OpenMP) and the baseline instruction set (4-lane
    windows): the same agreement with the backward, and identical bits for 1 and 2 threads."""
    code = """
import torch
from anigs.render import kernel as render_kernel, rasterize
from tests.render.test_composite_weights import _camera, _factors, _one_then_two_threads, _reference, EYES
from tests._scenes import random_scene
print(render_kernel.arch_flags(), render_kernel.thread_flags())
for W, H in ((64, 48), (70, 45)):
    scene = random_scene(3000, W, H, 0, seed=101)
    f = _factors(H, W, 2, seed=102)
    for eye in EYES[:2]:
        viewmat, K = _camera(eye, W, H)
        w1, w2 = _one_then_two_threads((*scene[:4], viewmat, K, W, H, f))
        ref = _reference(*scene[:4], viewmat, K, W, H, f)
        assert torch.equal(w1, w2)
        torch.testing.assert_close(w1, ref, rtol=1e-5, atol=1e-6)
print("ok")
"""
    full_env = dict(os.environ, ANIGS_CACHE=str(tmp_path), **env)
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=full_env, capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0 and "ok" in res.stdout, res.stdout[-2000:] + res.stderr[-3000:]
