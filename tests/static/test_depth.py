"""The static fit's depth loss from SfM tracks: targets, loss, schedule, and the fit with and without tracks."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov
from anigs.render import rasterize
from anigs.static.depth import DepthTarget, depth_loss, depth_targets, depth_weight
from anigs.static.fit import StaticConfig, fit_static, split_holdout

from test_fit import FAST, make_scene, sfm_points

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def scene():
    return make_scene()


def _tracks(points: np.ndarray, cams: list[Camera]) -> dict[str, np.ndarray]:
    """What the SfM stage writes for ``points`` [P,3]: per camera, rows (x, y, depth) of the points in front of
    it and inside its image."""
    out = {}
    for c in cams:
        uv, z = c.project(points)
        ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < c.width) & (uv[:, 1] >= 0) & (uv[:, 1] < c.height)
        out[c.name] = np.c_[uv[ok], z[ok]].astype(np.float32)
    return out


def _wall(z: float, n: int = 12) -> dict[str, torch.Tensor]:
    """A fronto-parallel wall of overlapping opaque splats at depth ``z`` in front of the identity camera."""
    xs, ys = np.meshgrid(np.linspace(-0.6, 0.6, n), np.linspace(-0.45, 0.45, n))
    means = np.c_[xs.ravel() * z / 2, ys.ravel() * z / 2, np.full(xs.size, z)]
    m = len(means)
    return {"means": torch.tensor(means, dtype=torch.float32, requires_grad=True),
            "quats": torch.tensor([[1.0, 0, 0, 0]] * m), "scales": torch.full((m, 3), 0.15 * z / 2),
            "opacities": torch.full((m,), 0.95), "colors": torch.full((m, 3), 0.5)}


CAM = Camera(intrinsics_from_fov(60, 64, 48), np.eye(4), 64, 48, "front.png")


def _render_wall(w: dict[str, torch.Tensor]):
    rgb, alpha, meta = rasterize(w["means"], w["quats"], w["scales"], w["opacities"], w["colors"],
                                 CAM.torch_viewmat(), CAM.torch_K(), CAM.width, CAM.height)
    return alpha, meta["depth"]


def _centre_target(depth: float) -> DepthTarget:
    ys, xs = np.mgrid[16:32:4, 20:44:4]
    pixel = torch.from_numpy((ys * CAM.width + xs).ravel().astype(np.int64))
    return DepthTarget(pixel, torch.full((pixel.numel(),), float(np.log(depth))))


def test_zero_loss_where_the_depths_agree():
    w = _wall(2.0)
    alpha, depth = _render_wall(w)
    t = _centre_target(1.0)
    assert (alpha.reshape(-1)[t.pixel] > 0.5).all()
    agree = DepthTarget(t.pixel, depth.detach().reshape(-1)[t.pixel].log())
    assert float(depth_loss(depth, alpha, agree).detach()) == pytest.approx(0.0, abs=1e-6)
    # 10% too far: |log 1.1| at every point
    far = DepthTarget(t.pixel, agree.log_depth - np.log(1.1))
    assert float(depth_loss(depth, alpha, far)) == pytest.approx(np.log(1.1), rel=1e-4)
    # within the tolerance: nothing; beyond it: the excess
    assert float(depth_loss(depth, alpha, far, tolerance=0.1)) == 0.0
    assert float(depth_loss(depth, alpha, far, tolerance=0.05)) == pytest.approx(np.log(1.1) - 0.05, rel=1e-3)


def test_a_misplaced_wall_is_pulled_to_the_sfm_depth():
    w = _wall(3.0)
    target = _centre_target(2.0)
    opt = torch.optim.Adam([w["means"]], lr=0.02)
    losses = []
    for _ in range(60):
        alpha, depth = _render_wall(w)
        loss = depth_loss(depth, alpha, target)
        losses.append(float(loss))
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert losses[0] == pytest.approx(np.log(1.5), rel=0.02)
    assert losses[-1] < 0.2 * losses[0], losses[::10]
    alpha, depth = _render_wall(w)
    assert float(depth.reshape(-1)[target.pixel].median()) == pytest.approx(2.0, rel=0.1)


def test_transparent_pixels_are_left_out():
    w = _wall(2.0)
    alpha, depth = _render_wall(w)
    corner = DepthTarget(torch.tensor([0, CAM.width - 1]), torch.tensor([0.0, 0.0]))  # outside the wall
    assert (alpha.reshape(-1)[corner.pixel] < 0.5).all()
    assert float(depth_loss(depth, alpha, corner)) == 0.0


def test_targets_scale_with_the_photo_and_skip_held_out_photos():
    big = Camera(intrinsics_from_fov(60, 640, 480), np.eye(4), 640, 480, "a.png")
    small = big.scaled(64, 48)
    other = Camera(big.K, np.eye(4), 640, 480, "b.png").scaled(64, 48)
    tracks = {"a.png": np.array([[639.5, 479.5, 2.0], [10.0, 5.0, 4.0]], np.float32),
              "b.png": np.array([[1.0, 1.0, 1.0]], np.float32)}
    t = depth_targets(tracks, [(640, 480), (640, 480)], [small, other], [0])
    assert len(t) == 1
    assert t[0].pixel.tolist() == [47 * 64 + 63, 0 * 64 + 1]
    assert torch.allclose(t[0].log_depth, torch.log(torch.tensor([2.0, 4.0])))
    assert depth_targets({}, [(640, 480)], [small], [0]) == [None]


def test_bad_tracks_are_clear_errors(scene):
    gt, cams, imgs = scene
    sizes = [(c.width, c.height) for c in cams]
    with pytest.raises(ValueError, match="without a camera.*nope.png"):
        depth_targets({"nope.png": np.ones((1, 3), np.float32)}, sizes, cams, [1])
    with pytest.raises(ValueError, match="img_001.png.*outside its 64x48"):
        depth_targets({"img_001.png": np.array([[70.0, 3.0, 1.0]], np.float32)}, sizes, cams, [1])
    p, c = sfm_points(gt, every=4)
    bad = _tracks(p, cams)
    bad["img_002.png"][0, 2] = np.nan
    with pytest.raises(ValueError, match="img_002.png.*non-finite"):
        fit_static(imgs, cams, p, c, StaticConfig.from_dict({**FAST, "depth_weight": 0.5}), progress=False, tracks=bad)
    with pytest.raises(ValueError, match="depth_weight"):
        StaticConfig.from_dict({"depth_weight": -1})


def test_depth_weight_decays_from_first_to_final():
    assert depth_weight(0, 100, 0.0, 0.0) == 0.0 == depth_weight(50, 100, 0.0, 0.5)
    assert depth_weight(0, 100, 1.0, 0.01) == pytest.approx(1.0)
    assert depth_weight(50, 100, 1.0, 0.01) == pytest.approx(0.1)
    assert depth_weight(100, 100, 1.0, 0.01) == pytest.approx(0.01)
    assert depth_weight(50, 100, 0.4, 0.0) == pytest.approx(0.2)


def test_fit_without_tracks_or_weight_is_the_fit_without_depth(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    tracks = _tracks(p, cams)
    cfg = StaticConfig.from_dict(FAST)
    g0, m0 = fit_static(imgs, cams, p, c, cfg, progress=False)
    g1, m1 = fit_static(imgs, cams, p, c, cfg, progress=False, tracks=tracks)  # weight 0: only reported
    for k, v in g0.params().items():
        assert torch.equal(v, g1.params()[k]), k
    assert "depth" not in m0
    _, test_idx = split_holdout(len(cams), cfg.holdout_every)
    assert m1["depth"]["test"]["views"] == len(test_idx)
    assert m1["depth"]["train_points"] == sum(len(tracks[cams[i].name]) for i in range(len(cams)) if i not in test_idx)


def test_depth_loss_moves_the_fit_toward_the_sfm_depths_and_is_deterministic(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4, noise=0.0)
    # the SfM points start half a unit farther away from every camera than the surface they came from
    centre = np.mean([cam.center for cam in cams], 0)
    far = p + 0.5 * (p - centre) / np.linalg.norm(p - centre, axis=1, keepdims=True)
    tracks = _tracks(gt.means.numpy()[::4], cams)  # the true depths
    # Adam moves a mean by about its learning rate per step, whatever the loss: steps enough to cover some of it
    base = {**FAST, "iterations": 120, "lr_means": 1e-3, "background": [0.0, 0.0, 0.0]}
    cfg0 = StaticConfig.from_dict(base)
    cfg1 = StaticConfig.from_dict({**base, "depth_weight": 1.0, "depth_weight_final": 0.1})
    _, m0 = fit_static(imgs, cams, far, c, cfg0, progress=False, tracks=tracks)
    g1, m1 = fit_static(imgs, cams, far, c, cfg1, progress=False, tracks=tracks)
    g2, m2 = fit_static(imgs, cams, far, c, cfg1, progress=False, tracks=tracks)
    assert m1["depth"]["train"]["median_rel"] < 0.85 * m0["depth"]["train"]["median_rel"], (m0["depth"], m1["depth"])
    for k, v in g1.params().items():
        assert torch.equal(v, g2.params()[k]), k
    assert json.dumps(m1["depth"]) == json.dumps(m2["depth"])


def test_cli_passes_the_tracks_file(scene, tmp_path, caplog):
    from anigs.cameras import save_cameras
    from anigs.cli import main
    from anigs.io import write_npz
    from anigs.sfm.tracks import save_tracks
    from anigs.video import save_png

    gt, cams, imgs = scene
    for cam, im in zip(cams, imgs):
        save_png(tmp_path / "images" / cam.name, im.numpy())
    save_cameras(tmp_path / "cameras.json", cams)
    p, c = sfm_points(gt, every=4)
    write_npz(tmp_path / "points.npz", xyz=p.astype(np.float32), rgb=c.astype(np.float32))
    save_tracks(tmp_path / "tracks.npz", _tracks(p, cams))
    args = ["static", "--images", str(tmp_path / "images"), "--cameras", str(tmp_path / "cameras.json"),
            "--points", str(tmp_path / "points.npz"), "--no-progress"]
    params = json.dumps({**FAST, "depth_weight": 0.2})
    assert main([*args, "--out", str(tmp_path / "a"), "--tracks", str(tmp_path / "tracks.npz"), "--params", params]) == 0
    m = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert m["inputs"]["tracks"] == str(tmp_path / "tracks.npz") and m["depth"]["weight"] == 0.2
    assert m["config"]["depth_weight"] == 0.2
    # tracks of another capture: a clear error (exit status 1) naming an image
    save_tracks(tmp_path / "other.npz", {"elsewhere.png": np.ones((2, 3), np.float32)})
    caplog.clear()
    assert main([*args, "--out", str(tmp_path / "b"), "--tracks", str(tmp_path / "other.npz"), "--params", params]) == 1
    assert "without a camera, e.g. ['elsewhere.png']" in caplog.text
