"""Export (frame sequence, compact animated PLY) and final-render helpers."""
from __future__ import annotations

import json

import numpy as np
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.cli import main as cli
from anigs.animate.deform import DCTDeformation, save_model
from anigs.export import load_animated_ply, save_animated_ply
from anigs.animate.playback import moving_camera_path, most_animated_row_col, pingpong_times, slice_images, static_change
from anigs.gaussians import Gaussians, load_ply


def _scene(n=40, seed=0):
    g = torch.Generator().manual_seed(seed)
    return Gaussians(torch.randn(n, 3, generator=g), torch.randn(n, 4, generator=g), torch.randn(n, 3, generator=g) - 3,
                     torch.randn(n, generator=g), torch.randn(n, 4, 3, generator=g))


def _deformation(n=40, T=9, K=4):
    d = DCTDeformation(torch.tensor([1, 5, 7, 30]), T, K, num_gaussians=n)
    with torch.no_grad():
        d.pos_coeffs.normal_(0, 0.1, generator=torch.Generator().manual_seed(1))
        d.rot_coeffs.normal_(0, 0.2, generator=torch.Generator().manual_seed(2))
    return d


def test_animated_ply_roundtrip(tmp_path):
    g, d = _scene(), _deformation()
    save_animated_ply(tmp_path / "a.ply", g, d)
    g2, d2 = load_animated_ply(tmp_path / "a.ply", num_frames=9)
    assert torch.equal(d2.dynamic_index, d.dynamic_index)
    for t in (0, 3.5, 8):
        a, b = d(g, t), d2(g2, t)
        assert torch.allclose(a.means, b.means, atol=1e-6) and torch.allclose(a.quats, b.quats, atol=1e-6)
    # a plain 3DGS reader sees the static canonical scene
    plain = load_ply(tmp_path / "a.ply")
    assert torch.equal(plain.means, g.means)


def test_export_cli(tmp_path):
    g, d = _scene(), _deformation()
    g.save_ply(tmp_path / "static" / "canonical.ply")
    save_model(tmp_path / "round1" / "model.pt", d, g, {})
    src = ["export", "--static", str(tmp_path / "static"), "--model", str(tmp_path / "round1")]
    assert cli([*src, "--out", str(tmp_path / "exp"), "--params", '{"frames": true, "frame_step": 4}']) == 0
    meta = json.loads((tmp_path / "exp" / "animated.json").read_text())
    assert meta["frames"] == ["frames/frame_0000.ply", "frames/frame_0004.ply", "frames/frame_0008.ply"]
    f4 = load_ply(tmp_path / "exp" / meta["frames"][1])
    assert torch.allclose(f4.means, d(g, 4).means, atol=1e-6)
    static = torch.ones(40, dtype=torch.bool)
    static[d.dynamic_index] = False
    assert torch.equal(f4.means[static], g.means[static])
    # the compact scene is always written and reproduces every frame exactly
    from anigs.viewer.compact import load_compact

    assert meta["compact"] == "scene.anigs"
    scene = load_compact(tmp_path / "exp" / "scene.anigs")
    assert torch.equal(scene.frame(4).means, d(g, 4).means)
    # the static scene as SPZ (within its 1/4096 position steps) and glTF (positions exactly)
    from anigs.formats.spz import load_spz

    assert meta["static"]["glb"] == "canonical.glb" and meta["static"]["spz"] == "canonical.spz"
    assert (load_spz(tmp_path / "exp" / "canonical.spz").means - g.means).abs().max() <= 0.5 / 4096 + 1e-6
    raw = (tmp_path / "exp" / "canonical.glb").read_bytes()
    n = int.from_bytes(raw[12:16], "little")
    doc = json.loads(raw[20:20 + n])
    pos = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert raw[:4] == b"glTF" and pos["count"] == 40 and np.allclose(pos["min"], g.means.min(0).values.numpy())
    # per-frame PLYs only on request (export.frames)
    assert cli([*src, "--out", str(tmp_path / "exp2")]) == 0
    meta2 = json.loads((tmp_path / "exp2" / "animated.json").read_text())
    assert meta2["frames"] == [] and not (tmp_path / "exp2" / "frames").exists()
    assert (tmp_path / "exp2" / "scene.anigs").stat().st_size < sum(
        p.stat().st_size for p in (tmp_path / "exp" / "frames").glob("*.ply"))


def test_pingpong_is_continuous_and_in_range():
    t = pingpong_times(50, 9, speed=0.7)
    assert float(t.min()) >= 0 and float(t.max()) <= 8
    assert float((t[1:] - t[:-1]).abs().max()) <= 0.7 + 1e-9


def test_camera_path_passes_through_keys():
    cams = [Camera(intrinsics_from_fov(60, 32, 24), look_at([i, 0, 1.5], [i, 5, 1]), 32, 24) for i in range(5)]
    path = moving_camera_path(cams, 21, num_keys=5)
    assert np.allclose(path[0].center, cams[0].center) and np.allclose(path[-1].center, cams[-1].center)
    assert all(np.allclose(p.R @ p.R.T, np.eye(3), atol=1e-9) for p in path)


def test_slices_find_the_moving_patch():
    T, H, W = 12, 20, 30
    clip = np.full((T, H, W, 3), 0.5, np.float32)
    clip[:, 7, 11] = np.sin(np.arange(T))[:, None] * 0.4 + 0.5
    row, col, peak = most_animated_row_col(clip)
    assert (row, col) == (7, 11) and peak > 0.1
    xt, yt = slice_images(clip, row, col, upsample=3)
    assert xt.shape == (T * 3, W, 3) and yt.shape == (H, T * 3, 3)
    mask = np.zeros((H, W), bool)
    mask[7, 11] = True
    assert static_change(clip, mask) == 0.0 and static_change(clip, None) > 0.3
