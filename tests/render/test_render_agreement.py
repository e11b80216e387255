"""The cpu kernel against the pure-torch reference, and both against gsplat's torch oracle."""
from __future__ import annotations

import pytest
import torch

from anigs.render import rasterize
from anigs.render.projection import covariance_3d, project_gaussians
from anigs.geometry.sh import eval_sh
from tests._scenes import random_scene

CASES = [  # (N, sh_degree, seed, W, H)
    (1, 0, 0, 32, 24),
    (100, 1, 1, 64, 48),
    (2000, 0, 2, 64, 48),
    (2000, 2, 3, 80, 60),
    (5000, 3, 4, 96, 72),
    (20000, 0, 5, 96, 72),
    (20000, 3, 6, 64, 48),
]


def _render_with_grads(scene, W, H, deg, backend, weights):
    means, quats, scales, opac, colors, viewmat, K = scene
    leaves = [t.clone().requires_grad_(True) for t in (means, quats, scales, opac, colors)]
    rgb, alpha, meta = rasterize(*leaves, viewmat, K, W, H, sh_degree=deg if deg else None,
                                 background=torch.tensor([0.1, 0.5, 0.9]), backend=backend)
    wr, wa, wd = weights
    loss = (rgb * wr).sum() + (alpha * wa).sum() + (meta["depth"] * wd).sum()
    loss.backward()
    return rgb.detach(), alpha.detach(), meta["depth"].detach(), [t.grad for t in leaves]


@pytest.mark.parametrize("n,deg,seed,W,H", CASES)
def test_cpu_matches_torch(n, deg, seed, W, H):
    scene = random_scene(n, W, H, deg, seed)
    g = torch.Generator().manual_seed(100 + seed)
    weights = (torch.randn(H, W, 3, generator=g), torch.randn(H, W, generator=g), 0.1 * torch.randn(H, W, generator=g))
    r_t, a_t, d_t, g_t = _render_with_grads(scene, W, H, deg, "torch", weights)
    r_c, a_c, d_c, g_c = _render_with_grads(scene, W, H, deg, "cpu", weights)
    assert (r_t - r_c).abs().max() <= 1e-4
    assert (a_t - a_c).abs().max() <= 1e-4
    covered = a_t > 1e-2
    assert ((d_t - d_c).abs()[covered] <= 1e-4 * d_t.abs()[covered].clamp_min(1)).all()
    assert a_t.max() > 0.05, "scene must actually cover pixels"
    for name, gt, gc in zip(["means", "quats", "scales", "opacities", "colors"], g_t, g_c):
        assert torch.isfinite(gc).all(), name
        assert gt.norm() > 0, f"reference gradient for {name} is zero: test is not exercising it"
        cos = torch.nn.functional.cosine_similarity(gt.flatten().double(), gc.flatten().double(), dim=0)
        rel = (gt - gc).norm() / gt.norm()
        assert cos >= 0.999, (name, float(cos))
        assert rel <= 1e-3, (name, float(rel))


def test_cpu_deterministic_across_thread_counts():
    W, H = 96, 72
    scene = random_scene(5000, W, H, 1, seed=7)
    weights = (torch.ones(H, W, 3), torch.ones(H, W), torch.zeros(H, W))
    old = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        a = _render_with_grads(scene, W, H, 1, "cpu", weights)
        torch.set_num_threads(max(2, old))
        b = _render_with_grads(scene, W, H, 1, "cpu", weights)
    finally:
        torch.set_num_threads(old)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    for ga, gb in zip(a[3], b[3]):
        assert torch.equal(ga, gb)


def test_torch_composite_gradcheck():
    """Analytic gradients of the reference compositor against finite differences (float64)."""
    from anigs.render.torch_backend import composite_torch

    g = torch.Generator().manual_seed(0)
    M, W, H = 4, 7, 5
    means2d = (torch.rand(M, 2, generator=g, dtype=torch.float64) * torch.tensor([W, H])).requires_grad_()
    conics = torch.tensor([[0.3, 0.05, 0.25]] * M, dtype=torch.float64).requires_grad_()
    feats = torch.rand(M, 4, generator=g, dtype=torch.float64).requires_grad_()
    opac = torch.empty(M, dtype=torch.float64).uniform_(0.3, 0.8, generator=g).requires_grad_()
    rects = torch.tensor([[0, 0, W, H]] * M, dtype=torch.int32)
    fn = lambda m, c, f, o: composite_torch(m, c, f, o, rects, W, H)
    assert torch.autograd.gradcheck(fn, (means2d, conics, feats, opac), eps=1e-6, atol=1e-5)


def test_projection_matches_gsplat_oracle():
    T = pytest.importorskip("gsplat.cuda._torch_impl", reason="gsplat not installed (pip install 'anigs[gsplat]')")
    W, H = 128, 96
    means, quats, scales, opac, colors, viewmat, K = random_scene(3000, W, H, 0, seed=3, dtype=torch.float64)
    # a rotated, translated camera so the view transform is exercised
    from anigs.cameras import look_at

    viewmat = torch.tensor(look_at([0.5, -0.3, 0.2], [0, 0, 4], up=[0, -1, 0]))
    ours = project_gaussians(means, quats, scales, opac, viewmat, K, W, H)
    covars, _ = T._quat_scale_to_covar_preci(quats, scales, compute_preci=False)
    assert torch.allclose(covars, covariance_3d(quats, scales), atol=1e-12)
    radii, m2d, depths, conics, _ = T._fully_fused_projection(means, covars, viewmat[None], K[None], W, H)
    v = ours.valid
    assert v.sum() > 1000
    assert (ours.means2d[v] - m2d[0][v]).abs().max() < 1e-5
    assert (ours.depths[v] - depths[0][v]).abs().max() < 1e-5
    assert (ours.conics[v] - conics[0][v]).abs().max() < 1e-5
    # float32 as well, with a relative tolerance
    f = [t.float() for t in (means, quats, scales, opac, viewmat, K)]
    o32 = project_gaussians(*f[:4], f[4], f[5], W, H)
    assert ((o32.means2d[v].double() - m2d[0][v]).abs() / m2d[0][v].abs().clamp_min(1)).max() < 1e-5


@pytest.mark.parametrize("deg", [0, 1, 2, 3])
def test_sh_matches_gsplat_oracle(deg):
    T = pytest.importorskip("gsplat.cuda._torch_impl", reason="gsplat not installed (pip install 'anigs[gsplat]')")
    g = torch.Generator().manual_seed(deg)
    dirs = torch.nn.functional.normalize(torch.randn(500, 3, generator=g), dim=-1)
    coeffs = torch.randn(500, 16, 3, generator=g)
    ref = T._spherical_harmonics(deg, dirs, coeffs)
    assert (eval_sh(deg, coeffs, dirs) - ref).abs().max() < 1e-5


def test_fused_projection_matches_torch_projection():
    """The cpu backend's fused C++ projection (forward + analytic backward) against autograd."""
    from anigs.cameras import look_at
    from anigs.render.cpu_backend import project_cpu

    W, H = 96, 72
    means, quats, scales, opac, _, _, K = random_scene(4000, W, H, 0, seed=9)
    means = means * torch.tensor([3.0, 3.0, 1.0])  # many splats off-screen: exercises the Jacobian clamp
    quats[:5] = 0  # zero quaternions too
    viewmat = torch.tensor(look_at([0.3, -0.2, 0.1], [0, 0, 4], up=[0, -1, 0]), dtype=torch.float32)
    g = torch.Generator().manual_seed(0)
    w_m, w_c, w_d = torch.randn(4000, 2, generator=g), torch.randn(4000, 3, generator=g), torch.randn(4000, generator=g)
    out = {}
    for name in ("torch", "cpu"):
        leaves = [t.clone().requires_grad_(True) for t in (means, quats, scales)]
        if name == "torch":
            p = project_gaussians(*leaves, opac, viewmat, K, W, H)
            m2d, con, dep, rects, valid = p.means2d, p.conics, p.depths, p.rects, p.valid
        else:
            m2d, con, dep, rects, _, valid = project_cpu(*leaves, opac, viewmat, K, W, H)
        v = valid.detach()
        ((m2d * w_m)[v].sum() + (con * w_c)[v].sum() + (dep * w_d)[v].sum()).backward()
        out[name] = (m2d.detach(), con.detach(), dep.detach(), rects, v, [t.grad for t in leaves])
    a, b = out["torch"], out["cpu"]
    assert torch.equal(a[4], b[4]) and a[4].sum() > 500 and (~a[4]).sum() > 500
    v = a[4]
    for x, y in zip(a[:3], b[:3]):
        assert ((x[v] - y[v]).abs() / x[v].abs().clamp_min(1)).max() < 1e-5
    assert (a[3] != b[3]).sum() <= 2  # integer boxes: at most a rounding tie differs
    for ga, gb in zip(a[5], b[5]):
        cos = torch.nn.functional.cosine_similarity(ga.flatten().double(), gb.flatten().double(), dim=0)
        assert cos >= 0.9999 and (ga - gb).norm() / ga.norm() <= 1e-4
