"""DCT deformation field: basis, identity at zero, static rows untouched, rotations, limits, model.pt."""
from __future__ import annotations

import logging
import math

import pytest
import torch

from anigs.animate.frames import render_clip, render_frame
from anigs.animate.deform import (DCTDeformation, axis_angle_to_quat, dct_basis, dynamic_index_from_mask, load_model,
                          quat_multiply, resolve_num_bases, save_model, soft_limit)
from anigs.gaussians import Gaussians
from anigs.geometry.quaternion import quat_to_rotmat
from tests._scenes import ring_cameras, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")


def random_field(idx: torch.Tensor, T: int, K: int, n: int, scale: float = 0.05, seed: int = 1,
                 rotation: bool = True) -> DCTDeformation:
    d = DCTDeformation(idx, T, K, rotation=rotation, num_gaussians=n)
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        d.pos_coeffs.copy_(torch.randn(d.pos_coeffs.shape, generator=g) * scale)
        if rotation:
            d.rot_coeffs.copy_(torch.randn(d.rot_coeffs.shape, generator=g) * 0.3)
    return d


# ---- basis ----------------------------------------------------------------------------------
def test_basis_matches_paper_equation_and_is_orthogonal():
    T, K = 9, 6
    b = dct_basis(torch.arange(T), T, K, dtype=torch.float64)
    assert b.shape == (T, K)
    for t in (0, 3, 8):
        for k in (1, 4, 6):
            want = math.sqrt(2 / (K + 1)) * math.cos(math.pi / (2 * T) * (2 * t + 1) * k)
            assert b[t, k - 1].item() == pytest.approx(want, abs=1e-12)
    # the k = 1..T-1 DCT-II bases are orthogonal and zero-mean over the T integer frames
    gram = b.T @ b
    assert torch.allclose(gram - torch.diag(torch.diagonal(gram)), torch.zeros(K, K, dtype=torch.float64), atol=1e-12)
    assert torch.allclose(b.sum(0), torch.zeros(K, dtype=torch.float64), atol=1e-12)
    # fractional t: the same continuous formula between frames
    mid = dct_basis(2.5, T, K, dtype=torch.float64)
    want = [math.sqrt(2 / (K + 1)) * math.cos(math.pi / (2 * T) * 6 * k) for k in range(1, K + 1)]
    assert torch.allclose(mid, torch.tensor(want, dtype=torch.float64), atol=1e-12)
    assert dct_basis(torch.tensor([0.0, 2.5]), T, K).shape == (2, K)


def test_k_larger_than_t_refused_or_clamped(caplog):
    with pytest.raises(ValueError, match="K must be <= T-1"):
        DCTDeformation(torch.arange(3), num_frames=5, num_bases=5)
    log = logging.getLogger("test")
    with caplog.at_level(logging.WARNING, logger="test"):
        assert resolve_num_bases(16, 5, log) == 4
    assert "clamped to K=4" in caplog.text
    assert resolve_num_bases(3, 5, log) == 3


def test_single_frame_clip_works():
    G, mask = sway_scene(n_dyn=20, grid=3)
    idx = dynamic_index_from_mask(mask)
    d = DCTDeformation(idx, num_frames=1, num_bases=resolve_num_bases(8, 1), num_gaussians=G.num)
    assert d.num_bases == 0
    out = d(G, 0)
    assert torch.equal(out.means, G.means) and torch.equal(out.quats, G.quats)
    with pytest.raises(ValueError, match="outside"):
        d(G, 1)
    clip = render_clip(G, d, ring_cameras(1, 16, 12)[0], 1)
    assert clip.shape == (1, 12, 16, 3)


# ---- identity and static rows ----------------------------------------------------------
def test_zero_coefficients_are_exactly_the_identity():
    G, mask = sway_scene(n_dyn=50, grid=5, anisotropic=True)
    G.quats = G.quats * 3.7  # unnormalised canonical quaternions stay bit-identical too
    d = DCTDeformation(dynamic_index_from_mask(mask), 13, 8, num_gaussians=G.num)
    for t in (0, 1, 6.25, 12):
        out = d(G, t)
        assert torch.equal(out.means, G.means)
        assert torch.equal(out.quats, G.quats)
        assert out.log_scales is G.log_scales and out.sh is G.sh and out.opacity_logits is G.opacity_logits


def test_static_rows_bit_identical_and_dynamic_rows_move():
    G, mask = sway_scene(n_dyn=50, grid=5, anisotropic=True)
    idx = dynamic_index_from_mask(mask)
    d = random_field(idx, 13, 6, G.num)
    cam = ring_cameras(1, 48, 36)[0]
    static = ~mask
    for t in (0, 3.5, 12):
        out = d(G, t)
        assert torch.equal(out.means[static], G.means[static])
        assert torch.equal(out.quats[static], G.quats[static])
        assert (out.means[mask] - G.means[mask]).abs().max() > 1e-3
    # a scene whose dynamic Gaussians are invisible renders bit-identical at every t
    hidden = G.detach()
    hidden.opacity_logits[mask] = -30.0
    frames = [render_frame(hidden, d, cam, t) for t in range(13)]
    assert all(torch.equal(frames[0], f) for f in frames[1:])


def test_only_dynamic_rows_are_computed():
    G, mask = sway_scene(n_dyn=10, grid=20)
    d = random_field(dynamic_index_from_mask(mask), 9, 4, G.num)
    dmu, dq = d.offsets(2)
    assert dmu.shape == (10, 3) and dq.shape == (10, 4)
    assert d.pos_coeffs.shape == (10, 3, 4) and d.rot_coeffs.shape == (10, 3, 4)


# ---- rotations --------------------------------------------------------------------------
def test_rotation_offset_exponential_map_and_composition():
    # 90 degrees about z
    q = axis_angle_to_quat(torch.tensor([[0.0, 0.0, math.pi / 2]], dtype=torch.float64))
    assert torch.allclose(q, torch.tensor([[math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]], dtype=torch.float64))
    g = torch.Generator().manual_seed(0)
    w = torch.randn(20, 3, generator=g, dtype=torch.float64)
    q0 = torch.randn(20, 4, generator=g, dtype=torch.float64)
    dq = axis_angle_to_quat(w)
    assert torch.allclose(dq.norm(dim=-1), torch.ones(20, dtype=torch.float64))
    qt = quat_multiply(dq, q0)
    assert torch.allclose(qt.norm(dim=-1), q0.norm(dim=-1))  # a unit offset keeps the canonical norm
    # composition = world-frame rotation after the canonical one
    assert torch.allclose(quat_to_rotmat(qt), quat_to_rotmat(dq) @ quat_to_rotmat(q0), atol=1e-10)


def test_zero_length_rotation_offset_has_finite_gradients():
    w = torch.zeros(4, 3, requires_grad=True)
    q = axis_angle_to_quat(w)
    assert torch.equal(q.detach(), torch.tensor([[1.0, 0, 0, 0]] * 4))
    (q[:, 1:] * torch.arange(1, 4.0)).sum().backward()
    assert torch.isfinite(w.grad).all()
    assert torch.allclose(w.grad, torch.arange(1, 4.0).expand(4, 3) * 0.5)  # d(sin(th/2) w/th)/dw = 1/2 at 0
    # through the rasterizer: an anisotropic Gaussian's image reacts to its rotation coefficients at zero
    G, mask = sway_scene(n_dyn=30, grid=3, anisotropic=True)
    d = DCTDeformation(dynamic_index_from_mask(mask), 9, 4, num_gaussians=G.num)
    img = render_frame(G, d, ring_cameras(1, 48, 36)[0], 2)
    (img * torch.linspace(0, 1, 48)[None, :, None]).sum().backward()
    assert torch.isfinite(d.rot_coeffs.grad).all() and d.rot_coeffs.grad.abs().max() > 0
    assert torch.isfinite(d.pos_coeffs.grad).all() and d.pos_coeffs.grad.abs().max() > 0
    # zero-length canonical quaternions (degenerate PLY rows) stay finite under rotation offsets
    G.quats[mask] = 0.0
    d2 = random_field(dynamic_index_from_mask(mask), 9, 4, G.num)
    d2.pos_coeffs.requires_grad_(True)
    img = render_frame(G, d2, ring_cameras(1, 48, 36)[0], 3.5)
    img.sum().backward()
    assert torch.isfinite(img).all() and torch.isfinite(d2.rot_coeffs.grad).all()
    assert torch.isfinite(d2.pos_coeffs.grad).all()


# ---- limits and extreme values ------------------------------------------------------------
def test_soft_limit_is_smooth_and_bounded():
    L = torch.tensor([0.1, 0.1, 0.1, 2.0])
    x = torch.tensor([[0.0, 0, 0], [1e-4, 0, 0], [3.0, 4.0, 0], [0.1, 0.0, 0.0]], requires_grad=True)
    y = soft_limit(x, L)
    assert torch.equal(y[0].detach(), torch.zeros(3))
    assert torch.allclose(y[1], x[1], rtol=1e-6)
    n2 = float(y[2].detach().norm())
    assert 0.099 < n2 <= 0.1 * (1 + 1e-6)
    assert torch.allclose(y[2] / y[2].norm(), x[2] / x[2].norm())  # direction kept
    assert torch.allclose(y[3], x[3], rtol=1e-3)  # well inside its limit: nearly unchanged
    y.sum().backward()
    assert torch.isfinite(x.grad).all()
    assert (x.grad[:2] > 0).any()
    # past the limit the squashing still passes a gradient (no hard clip)
    z = torch.tensor([[0.2, 0.0, 0.0]], requires_grad=True)
    soft_limit(z, torch.tensor([0.1]))[0, 0].backward()
    assert float(z.grad[0, 0]) > 0.01


def test_amplitude_limits_bound_offsets_and_angles():
    G, mask = sway_scene(n_dyn=40, grid=3)
    idx = dynamic_index_from_mask(mask)
    from anigs.animate.deform import offset_limits

    lim = offset_limits(G.means, idx, max_offset_frac=0.1)
    assert torch.allclose(lim, 0.1 * G.means[idx, 2])  # anchor = ground point: distance = height
    d = DCTDeformation(idx, 9, 4, max_offset=lim, max_angle=torch.tensor(math.radians(10)), num_gaussians=G.num)
    with torch.no_grad():
        d.pos_coeffs.fill_(50.0)
        d.rot_coeffs.fill_(50.0)
    for t in range(9):
        dmu, dq = d.offsets(t)
        assert bool((dmu.norm(dim=1) <= lim * (1 + 1e-5)).all())
        angle = 2 * torch.atan2(dq[:, 1:].norm(dim=1), dq[:, 0].abs())
        assert bool((angle <= math.radians(10) + 1e-5).all())


def test_huge_coefficients_render_finite():
    G, mask = sway_scene(n_dyn=40, grid=5, anisotropic=True)
    d = DCTDeformation(dynamic_index_from_mask(mask), 9, 4, num_gaussians=G.num)
    cam = ring_cameras(1, 32, 24)[0]
    for value in (1e6, 1e30, 3e38):
        with torch.no_grad():
            d.pos_coeffs.fill_(value)
            d.rot_coeffs.fill_(-value)
        for t in (0, 4.5, 8):
            out = d(G, t)
            out.check_finite("deformed")
            img = render_frame(G, d, cam, t)
            assert torch.isfinite(img).all()


# ---- selection, remapping, save/load ----------------------------------------------------------
def test_dynamic_index_from_mask():
    assert dynamic_index_from_mask(torch.tensor([0, 1, 0, 1], dtype=torch.bool)).tolist() == [1, 3]
    assert dynamic_index_from_mask(torch.tensor([0, 2, 1, 0])).tolist() == [1, 2]  # effect labels
    with pytest.raises(ValueError, match="3 entries but the canonical scene has 4"):
        dynamic_index_from_mask(torch.ones(3, dtype=torch.bool), 4)
    with pytest.raises(ValueError, match="duplicate"):
        DCTDeformation(torch.tensor([1, 1]), 5, 2)


def test_remapped_keeps_coefficients_of_gaussians_that_stay_dynamic():
    d = random_field(torch.tensor([2, 5, 7]), 9, 3, 10)
    r = d.remapped(torch.tensor([5, 6, 7]))
    assert torch.equal(r.pos_coeffs[0], d.pos_coeffs[1]) and torch.equal(r.pos_coeffs[2], d.pos_coeffs[2])
    assert torch.equal(r.pos_coeffs[1], torch.zeros(3, 3)) and torch.equal(r.rot_coeffs[1], torch.zeros(3, 3))


def test_model_roundtrip_with_canonical_ply(tmp_path):
    G, mask = sway_scene(n_dyn=30, grid=4, anisotropic=True)
    G.check_finite()
    ply = tmp_path / "canonical.ply"
    G.save_ply(ply)
    G = Gaussians.load_ply(ply)  # float32 round trip
    idx = dynamic_index_from_mask(mask)
    d = random_field(idx, 11, 5, G.num)
    trained = G.detach()
    trained.means[idx] += 0.01  # trained canonical positions of the dynamic Gaussians
    save_model(tmp_path / "model.pt", d, trained, config={"num_bases": 5})
    canon, d2, payload = load_model(tmp_path / "model.pt", ply)
    assert payload["config"] == {"num_bases": 5}
    assert torch.equal(canon.means, trained.means) and torch.equal(canon.quats, G.quats)
    assert torch.equal(d2.dynamic_index, idx) and (d2.num_frames, d2.num_bases) == (11, 5)
    for t in (0, 4, 10):
        a, b = d(trained, t), d2(canon, t)
        assert torch.equal(a.means, b.means) and torch.equal(a.quats, b.quats)
    with pytest.raises(ValueError, match="30 Gaussians|Gaussians"):
        load_model(tmp_path / "model.pt", G.subset(torch.arange(G.num - 1)))


def test_checkpoint_with_nan_is_refused(tmp_path):
    G, mask = sway_scene(n_dyn=10, grid=3)
    d = random_field(dynamic_index_from_mask(mask), 9, 3, G.num)
    with pytest.raises(ValueError, match="pos_coeffs"):
        with torch.no_grad():
            bad = random_field(dynamic_index_from_mask(mask), 9, 3, G.num)
            bad.pos_coeffs[0, 0, 0] = float("nan")
        save_model(tmp_path / "bad.pt", bad, G)
    assert not (tmp_path / "bad.pt").exists()
    save_model(tmp_path / "m.pt", d, G)
    payload = torch.load(tmp_path / "m.pt", weights_only=True)
    payload["deformation"]["rot_coeffs"][1, 2, 0] = float("inf")
    torch.save(payload, tmp_path / "m.pt")
    with pytest.raises(ValueError, match="deformation.rot_coeffs"):
        load_model(tmp_path / "m.pt")
    payload["deformation"]["rot_coeffs"][1, 2, 0] = 0.0
    payload["canonical_means"][3, 0] = float("nan")
    torch.save(payload, tmp_path / "m.pt")
    with pytest.raises(ValueError, match="canonical_means"):
        load_model(tmp_path / "m.pt")
    with pytest.raises(FileNotFoundError, match="missing.pt"):
        load_model(tmp_path / "missing.pt")


def test_render_clip_without_model_repeats_the_canonical_render():
    G, mask = sway_scene(n_dyn=20, grid=4)
    cam = ring_cameras(1, 32, 24)[0]
    clip = render_clip(G, None, cam, 7)
    assert clip.shape == (7, 24, 32, 3)
    assert all(torch.equal(clip[0], clip[t]) for t in range(7))
    assert torch.equal(clip[0], render_frame(G, None, cam, 0))
    d = random_field(dynamic_index_from_mask(mask), 7, 3, G.num)
    moving = render_clip(G, d, cam, 7)
    assert not torch.equal(moving[0], moving[3])
    with pytest.raises(ValueError, match="T=7"):
        render_clip(G, d, cam, 9)
