"""The fused cpu kernel (anigs/render/csrc) on paths the scene-level agreement tests do not
reach: SH degree 0 and unused SH coefficients, background gradients, strided upstream
gradients, concurrent and forked callers, and the baseline instruction-set build."""
from __future__ import annotations

import multiprocessing as mp
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import torch

from anigs.render import rasterize
from tests._scenes import random_scene

ROOT = Path(__file__).resolve().parents[2]


def _grads(scene, W, H, deg, backend, loss_fn, background=None):
    means, quats, scales, opac, colors, viewmat, K = scene
    leaves = [t.clone().requires_grad_(True) for t in (means, quats, scales, opac, colors)]
    bg = None if background is None else background.clone().requires_grad_(True)
    rgb, alpha, meta = rasterize(*leaves, viewmat, K, W, H, sh_degree=deg, background=bg, backend=backend)
    loss_fn(rgb, alpha, meta["depth"]).backward()
    out = [t.grad for t in leaves]
    return rgb.detach(), alpha.detach(), out + ([bg.grad] if bg is not None else [])


def _assert_close(gt, gc, name):
    assert torch.isfinite(gc).all(), name
    if gt.norm() == 0:
        assert gc.norm() == 0, name
        return
    cos = torch.nn.functional.cosine_similarity(gt.flatten().double(), gc.flatten().double(), dim=0)
    rel = (gt - gc).norm() / gt.norm()
    assert cos >= 0.999 and rel <= 1e-3, (name, float(cos), float(rel))


def _weighted(H, W, seed=0):
    g = torch.Generator().manual_seed(seed)
    wr, wa, wd = torch.randn(H, W, 3, generator=g), torch.randn(H, W, generator=g), 0.1 * torch.randn(H, W, generator=g)
    return lambda rgb, alpha, depth: (rgb * wr).sum() + (alpha * wa).sum() + (depth * wd).sum()


@pytest.mark.parametrize("deg,ncoef", [(0, 1), (0, 16), (1, 16), (2, 9), (3, 16)])
def test_sh_gradients_every_degree(deg, ncoef):
    """SH colour gradients (and the view-direction gradient into means) at degrees 0-3,
    including SH tensors with more coefficients than the degree uses (zero gradient there)."""
    W, H = 64, 48
    scene = list(random_scene(3000, W, H, 3, seed=20 + deg))
    scene[4] = scene[4][:, :ncoef].contiguous()
    loss = _weighted(H, W, deg)
    r_t, a_t, g_t = _grads(scene, W, H, deg, "torch", loss)
    r_c, a_c, g_c = _grads(scene, W, H, deg, "cpu", loss)
    assert (r_t - r_c).abs().max() <= 1e-4 and (a_t - a_c).abs().max() <= 1e-4
    for name, gt, gc in zip(["means", "quats", "scales", "opacities", "sh"], g_t, g_c):
        _assert_close(gt, gc, name)
    used = (deg + 1) ** 2
    assert g_c[4][:, :used].norm() > 0
    assert torch.equal(g_c[4][:, used:], torch.zeros_like(g_c[4][:, used:]))


def test_background_gradient():
    W, H = 48, 32
    scene = random_scene(1500, W, H, 0, seed=31)
    loss = _weighted(H, W, 1)
    bg = torch.tensor([0.2, 0.5, 0.7])
    _, _, g_t = _grads(scene, W, H, None, "torch", loss, background=bg)
    _, _, g_c = _grads(scene, W, H, None, "cpu", loss, background=bg)
    for name, gt, gc in zip(["means", "quats", "scales", "opacities", "colors", "background"], g_t, g_c):
        _assert_close(gt, gc, name)


@pytest.mark.parametrize("kind", ["expanded", "transposed", "rgb_only"])
def test_strided_upstream_gradients(kind):
    """The kernel reads upstream image gradients with their strides (no copies)."""
    W, H = 40, 30
    scene = random_scene(1200, W, H, 0, seed=41)
    g = torch.Generator().manual_seed(5)
    wt = torch.randn(W, H, 3, generator=g)
    losses = {
        "expanded": lambda rgb, alpha, depth: rgb.sum() + 2 * alpha.sum() + 0.1 * depth.sum(),
        "transposed": lambda rgb, alpha, depth: (rgb * wt.transpose(0, 1)).sum() + (alpha.t() * wt[..., 0]).sum(),
        "rgb_only": lambda rgb, alpha, depth: (rgb[::2, 1::3] ** 2).sum(),
    }
    _, _, g_t = _grads(scene, W, H, None, "torch", losses[kind])
    _, _, g_c = _grads(scene, W, H, None, "cpu", losses[kind])
    for name, gt, gc in zip(["means", "quats", "scales", "opacities", "colors"], g_t, g_c):
        _assert_close(gt, gc, name)


def test_unused_outputs_match_zero_gradients():
    """Outputs that the loss does not use get no gradient tensor (the kernel skips them);
    the result equals the one with explicit zero gradients for them."""
    W, H = 40, 30
    scene = random_scene(1200, W, H, 0, seed=43)
    wt = torch.randn(H, W, 3, generator=torch.Generator().manual_seed(6))
    _, _, g_none = _grads(scene, W, H, None, "cpu", lambda rgb, alpha, depth: (rgb * wt).sum())
    _, _, g_zero = _grads(scene, W, H, None, "cpu",
                          lambda rgb, alpha, depth: (rgb * wt).sum() + 0 * (alpha.sum() + depth.sum()))
    for name, a, b in zip(["means", "quats", "scales", "opacities", "colors"], g_none, g_zero):
        torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-9, msg=name)


def test_concurrent_renders_from_threads_match():
    """Two Python threads rendering at once (ctypes releases the GIL) get the serial results."""
    W, H = 64, 48
    scene = random_scene(4000, W, H, 1, seed=51)
    loss = _weighted(H, W, 2)
    ref = _grads(scene, W, H, 1, "cpu", loss)
    results = [None] * 4

    def work(i):
        results[i] = _grads(scene, W, H, 1, "cpu", loss)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for res in results:
        assert torch.equal(res[0], ref[0]) and torch.equal(res[1], ref[1])
        for a, b in zip(res[2], ref[2]):
            assert torch.equal(a, b)


def _child_render(q, kernel_threads):
    # libgomp is not fork-safe once used: like torch's DataLoader workers, keep torch (and an
    # OpenMP kernel) single-threaded in the child; the kernel's own pool may use two threads
    torch.set_num_threads(1)
    W, H = 32, 24
    scene = random_scene(500, W, H, 0, seed=61)
    torch.set_num_threads(kernel_threads)
    rgb, _, _ = rasterize(*scene, W, H, backend="cpu")
    torch.set_num_threads(1)
    q.put(rgb.double().sum().item())


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_render_in_forked_child():
    """A child forked after the kernel's threads started (e.g. DataLoader workers) renders."""
    W, H = 32, 24
    scene = random_scene(500, W, H, 0, seed=61)
    expected = rasterize(*scene, W, H, backend="cpu")[0].double().sum().item()
    old = torch.get_num_threads()
    torch.set_num_threads(2)  # make sure the parent has pool workers running
    try:
        rasterize(*scene, W, H, backend="cpu")
        ctx = mp.get_context("fork")
        q = ctx.Queue()
        from anigs.render import kernel as render_kernel

        kernel_threads = 1 if render_kernel.thread_flags() else 2  # OpenMP build: 1, own pool: 2
        p = ctx.Process(target=_child_render, args=(q, kernel_threads))
        p.start()
        p.join(timeout=60)
        assert p.exitcode == 0
        assert q.get(timeout=5) == expected
    finally:
        torch.set_num_threads(old)


def test_baseline_instruction_set_build_agrees(tmp_path):
    """The kernel built for the baseline ISA (4-lane windows) against the torch reference."""
    code = """
import torch
from anigs.render import kernel as render_kernel, rasterize
from tests._scenes import random_scene
assert render_kernel.arch_flags() == []
W, H = 64, 48
scene = random_scene(3000, W, H, 2, seed=71)
out = {}
for b in ("torch", "cpu"):
    leaves = [t.clone().requires_grad_(True) for t in scene[:5]]
    rgb, alpha, meta = rasterize(*leaves, *scene[5:], W, H, sh_degree=2, backend=b)
    (rgb.sum() + alpha.sum() + meta["depth"].sum()).backward()
    out[b] = (rgb.detach(), [t.grad for t in leaves])
assert (out["torch"][0] - out["cpu"][0]).abs().max() <= 1e-4
for gt, gc in zip(out["torch"][1], out["cpu"][1]):
    assert (gt - gc).norm() <= 1e-3 * gt.norm()
print("ok")
"""
    env = dict(os.environ, ANIGS_KERNEL_ARCH="none", ANIGS_CACHE=str(tmp_path))
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr[-3000:]


@pytest.mark.parametrize("which", ["viewmat", "K", "scales", "opacities"])
def test_invalid_inputs_same_error_on_both_backends(which):
    """The cpu backend validates inside the kernel, with the reference path's messages."""
    W, H = 16, 12
    means, quats, scales, opac, colors, viewmat, K = (t.clone() for t in random_scene(10, W, H, 0, seed=81))
    if which == "viewmat":
        viewmat[0, 3] = float("nan")
    elif which == "K":
        K[0, 0] = float("inf")
    elif which == "scales":
        scales[3, 1] = -0.1
    else:
        opac[2] = 1.5
    messages = []
    for backend in ("torch", "cpu"):
        with pytest.raises(ValueError) as info:
            rasterize(means, quats, scales, opac, colors, viewmat, K, W, H, backend=backend)
        messages.append(str(info.value))
    assert messages[0] == messages[1]
    assert (which in messages[0]) if which in ("viewmat", "K") else ("scales" in messages[0])
