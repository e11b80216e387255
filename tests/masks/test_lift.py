"""Per-Gaussian visibility and 2D->3D mask lifting (anigs.masks.lift).

Also home of ``toy_scene``, the small labelled scene the views/masks tests share.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians
from anigs.geometry.propagate import propagate_labels
from anigs.masks.lift import LiftConfig, lift_masks, lift_masks_report
from anigs.render.visibility import (VisibilityConfig, blend_weights, check_mask, frustum_subset, render_depth,
                                     visibility)
from anigs.render import render_gaussians
from anigs.synth.scene import SKY


def toy_scene(seed: int = 0, ring: int = 10, width: int = 96, height: int = 72, lawn: bool = False,
              ground_noise: float = 0.0):
    """A small labelled z-up scene and a ring of cameras around it.

    Labels: 0 ground (brown, or lawn green with ``lawn``), 1 grey wall, 4 green textured
    blobs (filled spheres, so some Gaussians are hidden inside). ``ground_noise`` (m, std):
    the ground splats scatter in height and tilt like a poorly fitted ground. Returns
    (Gaussians, labels int [N], cameras looking at the centre from 4.5 m, 1.5 m high).
    """
    rng = np.random.default_rng(seed)
    pts, cols, scl, lab = [], [], [], []
    g = np.arange(-4.0, 4.0, 0.12)
    gx, gy = np.meshgrid(g, g)
    p = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], 1)
    p[:, :2] += rng.normal(0, 0.02, (len(p), 2))
    base = np.array([0.30, 0.45, 0.16]) if lawn else np.array([0.45, 0.32, 0.2])
    pts.append(p), scl.append(np.tile([0.075, 0.075, 0.003], (len(p), 1))), lab.append(np.zeros(len(p), int))
    cols.append(base * rng.uniform(0.85, 1.15, (len(p), 1)))
    if ground_noise > 0:
        p[:, 2] += np.random.default_rng(seed + 1).normal(0, ground_noise, len(p))
    ys, zs = np.meshgrid(np.arange(-1.5, 1.5, 0.1), np.arange(0.05, 2.0, 0.1))
    face = np.stack([np.full(ys.size, 2.6), ys.ravel(), zs.ravel()], 1)
    pts.append(face), scl.append(np.full((len(face), 3), 0.07)), lab.append(np.ones(len(face), int))
    cols.append(np.array([0.55, 0.55, 0.57]) * rng.uniform(0.9, 1.1, (len(face), 1)))
    for c, r in (((-1.2, 1.0, 1.0), 0.6), ((-0.8, -1.4, 0.7), 0.5), ((0.9, 0.2, 1.3), 0.55)):
        n = 450
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        q = np.asarray(c) + d * r * rng.uniform(0.2, 1.0, (n, 1)) ** (1 / 3)
        pts.append(q), scl.append(np.full((n, 3), 0.08)), lab.append(np.full(n, 4))
        cols.append(np.clip(np.array([0.18, 0.55, 0.15]) * rng.uniform(0.6, 1.3, (n, 1))
                            + rng.normal(0, 0.03, (n, 3)), 0, 1))
    P = torch.tensor(np.concatenate(pts), dtype=torch.float32)
    C = torch.tensor(np.concatenate(cols), dtype=torch.float32)
    S = torch.tensor(np.concatenate(scl), dtype=torch.float32)
    gs = Gaussians.from_points(P, C, 0.01, opacity=0.9)
    gs.log_scales = S.log()
    if ground_noise > 0:  # tilt the scattered ground splats by up to ~35 degrees
        tilt = np.random.default_rng(seed + 2).normal(0, 0.3, (len(p), 3))
        q = np.concatenate([np.ones((len(p), 1)), tilt], 1)
        gs.quats[: len(p)] = torch.tensor(q / np.linalg.norm(q, axis=1, keepdims=True), dtype=torch.float32)
    K = intrinsics_from_fov(70, width, height)
    cams = []
    for i in range(ring):
        a = 2 * math.pi * i / ring + 0.3
        eye = (4.5 * math.cos(a), 4.5 * math.sin(a), 1.5)
        cams.append(Camera(K, look_at(eye, (0, 0, 0.8)), width, height, f"c{i:02d}"))
    return gs, np.concatenate(lab), cams


@pytest.fixture(scope="module")
def scene():
    return toy_scene()


def test_frustum_cull_is_exact(scene):
    gs, _, cams = scene
    for cam in cams[:3]:
        idx = frustum_subset(gs, cam)
        assert 0 < len(idx) < gs.num
        with torch.no_grad():
            full = render_gaussians(gs, cam)[0]
            cut = render_gaussians(gs.subset(idx), cam)[0]
        assert float((full - cut).abs().max()) < 1e-6


def test_blend_weights_sum_to_alpha(scene):
    """sum_i w_i(p) = alpha(p): the summed per-Gaussian weights equal the total alpha."""
    gs, _, cams = scene
    cam = cams[0]
    mask = np.zeros((cam.height, cam.width), bool)
    mask[:, : cam.width // 2] = True
    total, inside = blend_weights(gs, cam, mask)
    _, alpha = render_depth(gs, cam)
    assert total.sum() == pytest.approx(float(alpha.sum()), rel=1e-3)
    assert inside.sum() == pytest.approx(float(alpha[mask].sum()), rel=1e-3)
    assert np.all(inside <= total + 1e-5)


def test_occluded_gaussian_is_not_visible():
    """A small Gaussian behind an opaque wall is hidden for both tests; in front it is visible."""
    ys, zs = np.meshgrid(np.linspace(-2, 2, 41), np.linspace(-2, 2, 41))
    wall = np.stack([ys.ravel(), zs.ravel(), np.full(ys.size, 5.0)], 1)
    probes = np.array([[0.0, 0.0, 8.0], [0.0, 0.0, 3.0]])
    pts = torch.tensor(np.concatenate([wall, probes]), dtype=torch.float32)
    gs = Gaussians.from_points(pts, torch.full((len(pts), 3), 0.5), 0.08, opacity=0.99)
    cam = Camera(intrinsics_from_fov(60, 64, 48), np.eye(4), 64, 48, "c")
    for mode in ("depth", "weight"):
        vis = visibility(gs, cam, VisibilityConfig(mode=mode))
        assert not vis[-2], mode
        assert vis[-1], mode
    assert visibility(gs, cam, VisibilityConfig(mode="frustum"))[-2]  # frustum ignores occlusion


@pytest.mark.parametrize("mode", ["depth", "weight"])
def test_lift_label_masks_precision_recall(scene, mode):
    """Masks rendered from known labels lift back to those labels (precision, recall >= 0.9)."""
    from anigs.masks import compute_masks, render_frames

    gs, lab, cams = scene
    truth = lab == 4
    frames = render_frames(gs, cams, SKY)
    masks = [m["dynamic"] for m in compute_masks("labels", frames, gaussians=gs, labels=lab, dynamic_labels=[4])]
    dyn, info = lift_masks_report(gs, cams, masks, LiftConfig(visibility=mode, propagate_k=8))
    tp = (dyn & truth).sum()
    precision, recall = tp / dyn.sum(), tp / truth.sum()
    assert precision >= 0.9 and recall >= 0.9, (mode, precision, recall, info)
    # without propagation, the Gaussians never seen stay static: recall can only drop
    dyn0 = lift_masks(gs, cams, masks, visibility=mode, propagate_k=0)
    assert (dyn0 & truth).sum() <= tp
    assert info["undecided"] + info["decided"] == gs.num


def test_lift_votes_threshold_and_min_views(scene):
    gs, lab, cams = scene
    h, w = cams[0].height, cams[0].width
    full = [np.ones((h, w), bool)] * len(cams)
    empty = [np.zeros((h, w), bool)] * len(cams)
    assert not lift_masks(gs, cams, empty, visibility="frustum").any()
    seen = lift_masks(gs, cams, full, visibility="frustum")
    assert seen.any()
    # half of the views positive: dynamic at threshold 0.5, not at 0.75
    half = [full[0] if i % 2 == 0 else empty[0] for i in range(len(cams))]
    a = lift_masks(gs, cams, half, visibility="frustum", vote_threshold=0.5)
    b = lift_masks(gs, cams, half, visibility="frustum", vote_threshold=0.75)
    assert b.sum() < a.sum()
    # a Gaussian must be seen in at least min_views views
    c = lift_masks(gs, cams, full, visibility="frustum", min_views=len(cams) + 1)
    assert not c.any()


def test_lift_errors(scene):
    gs, _, cams = scene
    cam = cams[0]
    with pytest.raises(ValueError, match=r"96x72.*32x24|32x24.*96x72"):
        check_mask(np.zeros((24, 32), bool), cam)
    with pytest.raises(ValueError, match="2 cameras but 1 masks"):
        lift_masks(gs, cams[:2], [np.zeros((72, 96), bool)])
    with pytest.raises(ValueError, match="vote_threshold"):
        LiftConfig(vote_threshold=0.0)
    with pytest.raises(ValueError, match="unknown key"):
        LiftConfig.from_dict({"votes": 3})
    with pytest.raises(ValueError, match="full Gaussians"):
        lift_masks(gs.means, cams[:1], [np.zeros((72, 96), bool)], visibility="weight")


def test_propagate_labels():
    means = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [5, 0, 0], [5.1, 0, 0],
                      [0.05, 0.05, 0], [5.05, 0, 0]], float)
    decided = np.array([1, 1, 1, 1, 1, 0, 0], bool)
    value = np.array([1, 1, 1, 0, 0, 0, 0], bool)
    out = propagate_labels(means, decided, value, k=2)
    assert out[5] and not out[6]
    assert (out[:5] == value[:5]).all()
    assert (propagate_labels(means, decided, value, k=0) == value).all()


def test_lift_on_a_noisy_lawn_keeps_the_lawn_static():
    """Vegetation masks with the measured ground layer lift the blobs, not the scattered lawn."""
    from anigs.masks import compute_masks, render_frames
    from anigs.geometry.ground import ground_plane

    gs, lab, cams = toy_scene(lawn=True, ring=6, ground_noise=0.08)
    frames = render_frames(gs, cams, SKY)
    ground = ground_plane(gs.means.numpy(), np.array([0, 0, 1.0]), cams)
    truth = lab == 4

    def pr(vegetation):
        masks = [m["dynamic"] for m in compute_masks("vegetation", frames, ground=ground, config=vegetation)]
        dyn, _ = lift_masks_report(gs, cams, masks, LiftConfig(), ground=ground)
        tp = (dyn & truth).sum()
        return tp / max(dyn.sum(), 1), tp / truth.sum(), int((dyn & (lab == 0)).sum())

    p, r, lawn = pr({})
    assert p >= 0.7 and r >= 0.95, (p, r, lawn)
    # the fixed margin alone: the lawn that renders above it is lifted too
    p0, r0, lawn0 = pr({"ground_layer": 0.0})
    assert p0 < p - 0.2 and r0 >= 0.95 and lawn0 > 3 * lawn, (p0, p, lawn0, lawn)
