"""A similarity applied to Gaussians (anigs/geometry/transform.py): the image from the moved camera
is the image before, SH colours included; identity is exact; transforms compose."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.geometry.quaternion import quat_to_rotmat
from anigs.geometry.transform import rotate_sh, sh_band_matrices, transform_gaussians
from anigs.render import render_gaussians
from anigs.geometry.sh import eval_sh
from anigs.sfm.align import Similarity
from tests._scenes import random_scene

W, H = 64, 48
SIM = Similarity(2.5, Rotation.from_rotvec([0.3, -1.2, 0.7]).as_matrix(), np.array([1.0, -2.0, 0.5]))


def _scene(n: int = 400, deg: int = 3, seed: int = 0) -> tuple[Gaussians, Camera]:
    means, quats, scales, opac, sh, viewmat, K = random_scene(n, W, H, deg, seed)
    g = Gaussians(means, quats, scales.log(), torch.logit(opac), sh)
    return g, Camera(K.double().numpy(), viewmat.numpy(), W, H, "c")


def _render(g: Gaussians, cam: Camera) -> torch.Tensor:
    rgb, alpha, _ = render_gaussians(g, cam, background=torch.tensor([0.2, 0.3, 0.4]), backend="cpu")
    return rgb


def test_moved_scene_from_moved_camera_renders_the_same_image():
    g, cam = _scene()
    before = _render(g, cam)
    moved = transform_gaussians(g, SIM.scale, SIM.R, SIM.t)
    after = _render(moved, SIM.apply_camera(cam))
    assert (after - before).abs().max() < 1e-4
    assert before.std() > 0.05, "the scene must cover the image"
    # without rotating the SH the colours are wrong: the check above cannot pass by accident
    unrotated = Gaussians(moved.means, moved.quats, moved.log_scales, moved.opacity_logits, g.sh)
    assert (_render(unrotated, SIM.apply_camera(cam)) - before).abs().max() > 0.05


def test_rotated_sh_seen_along_the_rotated_direction_keeps_its_colour():
    gen = torch.Generator().manual_seed(1)
    sh = torch.randn(100, 16, 3, generator=gen, dtype=torch.float64)
    d = torch.nn.functional.normalize(torch.randn(100, 3, generator=gen, dtype=torch.float64), dim=1)
    R = torch.from_numpy(SIM.R)
    assert (eval_sh(3, rotate_sh(sh, SIM.R), d @ R.T) - eval_sh(3, sh, d)).abs().max() < 1e-12
    for m in sh_band_matrices(SIM.R, 3):  # the band matrices of an orthonormal basis are orthogonal
        assert np.abs(m @ m.T - np.eye(len(m))).max() < 1e-12
    assert rotate_sh(sh[:, :1], SIM.R).equal(sh[:, :1])  # DC alone: nothing to rotate


def test_identity_is_exact():
    g, _ = _scene(200)
    g.extras["label"] = torch.arange(g.num)
    h = transform_gaussians(g, 1.0, np.eye(3), np.zeros(3))
    for k, v in g.params().items():
        assert h.params()[k].dtype == torch.float32 and torch.equal(h.params()[k], v), k
    assert torch.equal(h.extras["label"], g.extras["label"])


def test_transforms_compose():
    g, _ = _scene(200)
    other = Similarity(0.7, Rotation.from_rotvec([-2.0, 0.4, 0.9]).as_matrix(), np.array([-0.3, 0.2, 4.0]))
    twice = transform_gaussians(transform_gaussians(g, SIM.scale, SIM.R, SIM.t), other.scale, other.R, other.t)
    both = other.compose(SIM)
    once = transform_gaussians(g, both.scale, both.R, both.t)
    assert (twice.means - once.means).abs().max() < 1e-5
    assert (twice.log_scales - once.log_scales).abs().max() < 1e-6
    assert (quat_to_rotmat(twice.quats) - quat_to_rotmat(once.quats)).abs().max() < 1e-6
    assert (twice.quats.norm(dim=1) - g.quats.norm(dim=1)).abs().max() < 1e-5  # the norm is kept
    assert (twice.sh - once.sh).abs().max() < 1e-5
    assert torch.equal(twice.opacity_logits, g.opacity_logits)


def test_refusals():
    g, _ = _scene(10)
    with pytest.raises(ValueError, match="reflection"):
        transform_gaussians(g, 1.0, np.diag([1.0, 1.0, -1.0]), np.zeros(3))
    with pytest.raises(ValueError, match="not orthogonal"):
        transform_gaussians(g, 1.0, 2 * np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="positive"):
        transform_gaussians(g, -1.0, np.eye(3), np.zeros(3))
