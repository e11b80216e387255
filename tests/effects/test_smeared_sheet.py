"""A crown the fit smeared in depth is a plant, not a wall (anigs.effects.outline).

On the street capture (a walk) the 15 dB fit spread a tree at the end of the street along the rays of
the photos that see it: 756 Gaussians on one sheet, which the plane rule set aside as a wall or floor
(recall 0.64 -> 0.49). Its sheet runs along the rays (|cos| 0.96) and a quarter of its outline sees
farther things; a picture flush on a wall does neither.
"""
from __future__ import annotations

import numpy as np

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.effects.config import REGIONS, EffectsConfig
from anigs.effects.geometry import render_features
from anigs.effects.outline import SmearedSheet, longest_axis, release_smeared, sheet_signs
from anigs.effects.photo_maps import PhotoMaps
from anigs.effects.rules import Candidate
from tests.effects.test_effects import _gaussians

GREEN, GREY = (0.2, 0.5, 0.15), (0.6, 0.58, 0.55)


def _street():
    """A wall across the end of a street (y = 8) with a green picture on it, and a green crown in front of it
    smeared along y from 2 to 5.5 (the fit's depth ambiguity); cameras walking up the street looking +y.
    Returns (Gaussians, picture indices, crown indices, PhotoMaps)."""
    rng = np.random.default_rng(3)
    wx, wz = np.meshgrid(np.arange(-5, 5, 0.08), np.arange(0, 4, 0.08))
    wall = np.column_stack([wx.ravel(), np.full(wx.size, 8.0), wz.ravel()])
    pic = (np.abs(wall[:, 0] - 2.0) < 0.8) & (np.abs(wall[:, 2] - 2.0) < 0.6)
    crown = np.column_stack([rng.normal(-1.2, 0.25, 700), rng.uniform(2.0, 5.5, 700), rng.normal(2.2, 0.3, 700)])
    means = np.vstack([wall, crown])
    n_w = len(wall)
    scales = np.vstack([np.tile([0.06, 0.06, 0.004], (n_w, 1)), np.tile([0.05, 0.05, 0.05], (700, 1))])
    normals = np.vstack([np.tile([0.0, -1, 0], (n_w, 1)), rng.normal(size=(700, 3))])
    cols = np.vstack([np.where(pic[:, None], GREEN, GREY), np.tile(GREEN, (700, 1))])
    g = _gaussians(means, scales, normals, cols, opacity=0.98)
    size = (160, 120)
    K = intrinsics_from_fov(60.0, *size)
    maps = []
    for i, y in enumerate(np.linspace(-3.0, -1.0, 5)):
        eye = np.array([0.3 * (i - 2), y, 1.6])
        cam = Camera(K, look_at(eye, np.array([0.0, 8.0, 1.8])), size[0], size[1], f"c{i}.png")
        _, a, d = render_features(g, np.zeros((g.num, 1), np.float32), cam)
        zero = np.zeros_like(a)
        maps.append(PhotoMaps(np.zeros((*a.shape, 3), np.float32), cam, d, a, zero, zero, zero))
    return g, np.flatnonzero(pic), n_w + np.arange(700), maps


def test_a_smeared_crown_runs_along_the_rays_and_stands_free_a_picture_does_neither():
    g, pic, crown, maps = _street()
    s_crown, s_pic = sheet_signs(g, [crown, pic], maps, EffectsConfig().photos.min_alpha)
    print(s_crown, s_pic)
    assert s_crown.photos == 5 and s_pic.photos == 5
    assert s_crown.along_rays >= 0.9 and s_crown.free_outline >= 0.5
    assert s_pic.along_rays <= 0.3 and s_pic.free_outline <= 0.05


def test_release_keeps_the_crown_and_leaves_the_picture_rejected():
    g, pic, crown, maps = _street()
    region = np.full(g.num, -1)
    means = g.means.double().numpy()
    cands = []
    for k, idx in enumerate((crown, pic)):
        cands.append(Candidate(k + 1, "foliage", idx, means[idx].mean(0), 1.0, kept=False, rule="plane", reason="plane"))
    release_smeared(g, cands, region, maps, EffectsConfig().rules.smeared_sheet, 0.5)
    assert cands[0].kept and cands[0].rule == "" and "smeared in depth" in cands[0].reason
    assert (region[crown] == REGIONS.index("foliage")).all()
    assert not cands[1].kept and cands[1].rule == "plane" and (region[pic] == -1).all()
    # switched off, nothing is released
    cands[0].kept, cands[0].rule = False, "plane"
    region[:] = -1
    release_smeared(g, cands, region, maps, SmearedSheet(free_outline=1.5), 0.5)
    assert not cands[0].kept and (region == -1).all()


def test_longest_axis():
    pts = np.random.default_rng(0).normal(size=(500, 3)) * [0.1, 3.0, 0.5]
    assert abs(longest_axis(pts)[1]) > 0.99
    assert not longest_axis(pts[:2]).any()
