"""Gaussians2Life-style lifting baseline, the shared baseline interface and DCT projection."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from anigs.animate.deform import load_model
from anigs.animate.frames import render_clip
from anigs.animate.update import ViewData
from anigs.baselines import BASELINES, fit_baseline, get_baseline, run_baseline
from anigs.baselines.base import trajectories_to_deformation
from anigs.baselines.registry import load_views
from anigs.baselines.lifting import LiftingConfig, fill_unobserved, fit, lift_displacements
from anigs.baselines.tracks import forward_tracks, projection_jacobians, sample_bilinear
from anigs.gaussians import Gaussians
from anigs.video import save_clip
from tests._scenes import ring_cameras, sway_motion, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")

T = 13


def swaying_views(n_views: int = 4):
    """A shrub swaying (DCT sway of tests._scenes) whose frame 0 is the canonical scene.

    Returns (canonical G, mask, views, ground-truth trajectories [T,D,3] float64)."""
    G, mask = sway_scene()
    gt = sway_motion(G, mask, T, K=4, amplitude=0.08)
    idx = gt.dynamic_index
    with torch.no_grad():
        off0 = gt.offsets(0)[0]
        shifted = G.means.clone()
        shifted[idx] -= off0  # so that the clip's frame 0 shows the canonical positions
        Gs = Gaussians(shifted, G.quats, G.log_scales, G.opacity_logits, G.sh)
        truth = gt.trajectories(Gs.means, torch.arange(T)).double()
    views = [ViewData(c, render_clip(Gs, gt, c, T)) for c in ring_cameras(n_views, 96, 72)]
    return G, mask, views, truth


def rel_rmse(traj: torch.Tensor, truth: torch.Tensor) -> float:
    disp = (truth - truth[:1]).norm(dim=-1)
    return float((traj - truth).norm(dim=-1).pow(2).mean().sqrt() / disp.pow(2).mean().sqrt())


# ---- building blocks ----------------------------------------------------------------------
def test_forward_tracks_follow_a_known_shift():
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.random((64, 80, 3)).astype(np.float32), (0, 0), 1.5)
    shifted = np.roll(img, (1, 2), axis=(0, 1))  # content moves +2 px in x, +1 px in y
    disp, valid = forward_tracks(np.stack([img, shifted]), "medium", 1.0)
    core = (slice(8, -8), slice(8, -8))
    assert np.all(disp[0] == 0)
    assert np.abs(disp[1][core][..., 0] - 2.0).mean() < 0.15
    assert np.abs(disp[1][core][..., 1] - 1.0).mean() < 0.15
    assert valid[1][core].mean() > 0.9


def test_sample_bilinear_and_jacobians():
    field = np.zeros((1, 4, 5, 1))
    field[0, :, :, 0] = np.arange(5)[None]           # value = column index
    uv = np.array([[0.5, 0.5], [2.0, 1.5], [4.5, 3.5]])  # pixel centres at integer + 0.5
    assert np.allclose(sample_bilinear(field, uv)[0, :, 0], [0.0, 1.5, 4.0])
    cam = ring_cameras(1, 96, 72)[0]
    x = np.array([[0.1, -0.2, 0.6], [0.3, 0.1, 0.9]])
    J = projection_jacobians(x, cam)
    eps = 1e-6
    for a in range(3):
        dx = np.zeros(3)
        dx[a] = eps
        num = (cam.project(x + dx)[0] - cam.project(x - dx)[0]) / (2 * eps)
        assert np.allclose(J[:, :, a], num, atol=1e-4)


def test_lift_two_views_exact_one_view_in_image_plane():
    rng = np.random.default_rng(1)
    D = 6
    J = rng.normal(size=(2, D, 2, 3)) * 40
    delta = rng.normal(size=(3, D, 3)) * 0.01
    disp = np.einsum("vdkj,tdj->vtdk", J, delta)
    w = np.ones((2, 3, D))
    est, obs = lift_displacements(J, disp, w, ridge=1e-9)
    assert obs.all()
    assert np.allclose(est, delta, atol=1e-6)
    # one view: the reprojection is exact and the component the view cannot see is zero
    est1, _ = lift_displacements(J[:1], disp[:1], w[:1], ridge=1e-9)
    assert np.allclose(np.einsum("dkj,tdj->tdk", J[0], est1), disp[0], atol=1e-6)
    null = np.stack([np.cross(J[0, d, 0], J[0, d, 1]) for d in range(D)])
    assert np.abs(np.einsum("tdj,dj->td", est1, null / np.linalg.norm(null, axis=1, keepdims=True))).max() < 1e-6
    # an unobserved Gaussian gets no displacement, then the neighbour fill
    w[:, 1, 2] = 0
    est2, obs2 = lift_displacements(J, disp, w)
    assert not obs2[1, 2] and np.all(est2[1, 2] == 0)
    pts = rng.normal(size=(D, 3))
    filled = fill_unobserved(pts, est2, obs2, k=2)
    assert np.abs(filled[1, 2]).sum() > 0 and np.array_equal(filled[obs2], est2[obs2])
    assert np.array_equal(fill_unobserved(pts, est2, obs2, k=0), est2)


def test_dct_projection_is_exact_with_the_full_basis():
    G, mask = sway_scene(n_dyn=20, grid=3)
    idx = torch.nonzero(mask).squeeze(1)
    traj = G.means.double()[idx][None] + 0.03 * torch.randn(T, idx.numel(), 3, generator=torch.Generator().manual_seed(0),
                                                            dtype=torch.float64)
    canon, d = trajectories_to_deformation(G, idx, traj, T - 1)
    with torch.no_grad():
        back = d.trajectories(canon.means.double(), torch.arange(T)).double()
    assert torch.allclose(back, traj, atol=1e-5)
    static = torch.ones(G.num, dtype=torch.bool)
    static[idx] = False
    assert torch.equal(canon.means[static], G.means[static])
    _, d4 = trajectories_to_deformation(G, idx, traj, 4)  # K < T-1: a least-squares low-pass
    assert d4.num_bases == 4
    with pytest.raises(ValueError, match="NaN"):
        trajectories_to_deformation(G, idx, traj * float("nan"), 4)


# ---- the baseline --------------------------------------------------------------------------
def test_lifting_recovers_a_multiview_motion_and_views_help():
    """Four views of a known sway: trajectories within 35% RMS of the truth; one view sees
    under half of the shrub and cannot see depth: clearly worse."""
    G, mask, views, truth = swaying_views(4)
    res = fit(G, mask, views, {"num_bases": T - 1})
    err4 = rel_rmse(res.trajectories, truth)
    err1 = rel_rmse(fit(G, mask, views[:1], {"num_bases": T - 1}).trajectories, truth)
    still = rel_rmse(G.means.double()[mask][None].expand(T, -1, -1), truth)
    print(f"lifting: relative RMSE 4 views {err4:.3f}, 1 view {err1:.3f}, no motion {still:.3f}")
    assert err4 < 0.35
    assert err4 < 0.6 * err1
    assert res.info["seen_by_two_or_more"] > 0 and len(res.info["visible_per_view"]) == 4
    # rendered like our model: static rows bit-identical at every frame
    static = ~mask
    for t in (0, 5, T - 1):
        g = res.deformation(res.canonical, t)
        assert torch.equal(g.means[static], G.means[static])
        assert torch.equal(g.quats, G.quats)


def test_empty_dynamic_set_and_input_errors():
    G, mask, views, _ = swaying_views(1)
    res = fit(G, torch.zeros_like(mask), views)
    assert res.deformation.num_dynamic == 0 and res.info["skipped"] == "empty dynamic set"
    assert torch.equal(res.deformation(res.canonical, 3).means, G.means)
    bad = [ViewData(views[0].camera, views[0].clip[:, :10])]
    with pytest.raises(ValueError, match="clip is"):
        fit(G, mask, bad)
    with pytest.raises(ValueError, match="no views"):
        fit(G, mask, [])
    with pytest.raises(KeyError, match="unknown keys"):
        fit(G, mask, views, {"nope": 1})
    with pytest.raises(ValueError, match="ridge"):
        LiftingConfig.from_dict({"ridge": 0})
    with pytest.raises(ValueError, match="unknown baseline"):
        get_baseline("sora")
    assert set(BASELINES) == {"lifting", "physics"}


def test_run_baseline_writes_a_loadable_model(tmp_path):
    G, mask, views, truth = swaying_views(2)
    ply = tmp_path / "canonical.ply"
    G.save_ply(ply)
    np.save(tmp_path / "dynamic.npy", mask.numpy())
    targets = []
    for v in views:
        p = tmp_path / f"{v.camera.name}.npz"
        save_clip(p, v.clip.numpy(), {"camera": v.camera.to_dict()})
        targets.append(p)
    out = tmp_path / "model.pt"
    res = run_baseline("lifting", ply, tmp_path / "dynamic.npy", targets, out, {"num_bases": 8},
                       log_json=tmp_path / "log.json")
    canon, d, payload = load_model(out, ply)
    assert payload["extra"]["method"] == "lifting" and d.num_bases == 8 and d.num_frames == T
    assert torch.equal(d.pos_coeffs, res.deformation.pos_coeffs)
    clip = render_clip(canon, d, views[0].camera, T)
    assert clip.shape == views[0].clip.shape
    # the rendered baseline moves inside the dynamic region and its motion resembles the target's
    assert float((clip[1:] - clip[:1]).abs().mean()) > 1e-4
    same = fit_baseline("lifting", G, mask, load_views(targets), {"num_bases": 8})
    assert torch.equal(same.deformation.pos_coeffs, d.pos_coeffs)  # deterministic, cameras from the clips
