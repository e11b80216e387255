"""Embedded synthetic demo scene: scene, ground-truth motion, capture, CLI."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from anigs.cameras import load_cameras
from anigs.gaussians import load_ply
from anigs.render import render_gaussians
from anigs.synth import (EFFECT_TYPES, LABEL_EFFECTS, LABEL_IDS, LABELS, WATER_LABEL, CameraPathConfig, MotionParams,
                         SceneConfig, SynthConfig, build_scene, camera_path, gt_clip_offsets, gt_offsets,
                         motion_tables, render_image, write_capture)

ROOT = Path(__file__).resolve().parents[2]
STATIC = [i for i, n in LABELS.items() if not LABEL_EFFECTS[n]]
MOVABLE = [i for i, n in LABELS.items() if LABEL_EFFECTS[n]]


@pytest.fixture(scope="module")
def scene():
    return build_scene(SceneConfig(), seed=0)


@pytest.fixture(scope="module")
def small_cfg():
    return SynthConfig.from_dict({"seed": 3, "scene": {"num_gaussians": 6000},
                                  "capture": {"num_images": 6, "width": 96, "height": 72}})


# ---- scene --------------------------------------------------------------------------
def test_scene_is_deterministic_for_a_seed():
    a, b = build_scene(SceneConfig(num_gaussians=6000), 5), build_scene(SceneConfig(num_gaussians=6000), 5)
    c = build_scene(SceneConfig(num_gaussians=6000), 6)
    for k, v in a.params().items():
        assert torch.equal(v, b.params()[k]), k
    assert torch.equal(a.extras["label"], b.extras["label"]) and torch.equal(a.extras["anchor"], b.extras["anchor"])
    assert a.num != c.num or not torch.equal(a.means, c.means)


def test_scene_size_labels_and_anchors(scene):
    n = scene.num
    assert 0.85 * 30000 <= n <= 1.15 * 30000
    labels, anchors = scene.extras["label"], scene.extras["anchor"]
    assert labels.shape == (n,) and anchors.shape == (n, 3)
    counts = torch.bincount(labels, minlength=len(LABELS))
    assert len(counts) == len(LABELS) and bool((counts > 50).all()), counts.tolist()
    static = torch.isin(labels, torch.tensor(STATIC))
    assert torch.equal(anchors[static], scene.means[static])  # static: anchor = own mean
    # movable anchors sit at the base: on the ground or on the planter, never above their Gaussian
    mov = ~static
    assert bool((anchors[mov, 2] <= scene.means[mov, 2] + 1e-6).all())
    assert bool((anchors[mov, 2] < 0.6).all())
    scene.check_finite()
    assert bool(((scene.opacities > 0) & (scene.opacities < 1)).all())
    rgb = scene.rgb
    assert bool(((rgb >= 0.0) & (rgb <= 1.0)).all())
    # z-up world with the ground at z=0: nothing far below ground, ground Gaussians at z ~ 0
    assert float(scene.means[:, 2].min()) > -0.05
    assert float(scene.means[labels == LABEL_IDS["ground"], 2].abs().max()) < 0.01


def test_scene_config_rejects_bad_values():
    with pytest.raises(ValueError, match="num_trees"):
        SceneConfig(num_trees=7)
    with pytest.raises(ValueError, match="bogus"):
        SceneConfig.from_dict({"bogus": 1})
    with pytest.raises(ValueError, match="num_gaussians"):
        SceneConfig.from_dict({"num_gaussians": "many"})


# ---- motion -------------------------------------------------------------------------
def test_static_labels_have_exactly_zero_offsets(scene):
    p = MotionParams()
    labels = scene.extras["label"]
    static = torch.isin(labels, torch.tensor(STATIC))
    for t in (0.0, 1.3, 7, torch.tensor(11.5), torch.linspace(0, 24, 9)):
        off = gt_offsets(p, scene.means, scene.extras["anchor"], labels, t)
        assert torch.count_nonzero(off[..., static, :]) == 0
    off = gt_offsets(p, scene.means, scene.extras["anchor"], labels, 6.0)
    for i in MOVABLE:
        assert float(off[labels == i].norm(dim=1).max()) > 1e-3, LABELS[i]


def test_offsets_zero_at_t0_loop_and_shapes(scene):
    p = MotionParams()
    m, a, lab = scene.means, scene.extras["anchor"], scene.extras["label"]
    assert torch.count_nonzero(gt_offsets(p, m, a, lab, 0.0)) == 0  # canonical = captured state
    t = torch.tensor([2.5, 9.0, 17.25])
    one = gt_offsets(p, m, a, lab, t)
    assert one.shape == (3, scene.num, 3)
    later = gt_offsets(p, m, a, lab, t + p.frames)
    assert torch.allclose(one, later, atol=2e-5)  # periodic with period T: a loop
    clip = gt_clip_offsets(p, m, a, lab)
    assert clip.shape == (p.frames, scene.num, 3)
    assert torch.allclose(clip[9], gt_offsets(p, m, a, lab, 9.0))
    mag = clip.norm(dim=2).max()
    assert 0.02 < float(mag) < 0.3  # visible but gentle (metres)


@pytest.mark.parametrize("label", ["foliage", "grass", "flowers"])
def test_amplitude_grows_with_height_above_anchor(label):
    h = torch.linspace(0.0, 4.0 if label == "foliage" else 0.5, 12)
    means = torch.stack([torch.full_like(h, 1.0), torch.full_like(h, -2.0), h], 1)
    anchors = torch.tensor([[1.0, -2.0, 0.0]]).expand(len(h), 3)
    labels = torch.full((len(h),), LABEL_IDS[label])
    no_flutter = MotionParams.from_dict({"effects": {"leaf_flutter": {"amplitude": 0.0}}})
    for params, strict in ((no_flutter, True), (MotionParams(), False)):
        rms = gt_clip_offsets(params, means, anchors, labels).norm(dim=2).pow(2).mean(0).sqrt()
        assert float(rms[0]) == 0.0  # no motion at the anchor
        if strict:
            assert bool((rms[1:] > rms[:-1]).all()), rms
        else:
            assert float(rms[-1]) > float(rms[len(h) // 2]) > float(rms[1])


def test_motion_is_spatially_coherent_and_follows_the_wind():
    p = MotionParams()
    base = torch.tensor([[0.5, 0.5, 3.5]])
    means = torch.cat([base, base + torch.tensor([[0.02, 0.0, 0.0]]), base + torch.tensor([[0.0, 6.0, 0.0]])])
    anchors = means.clone()
    anchors[:, 2] = 0
    labels = torch.full((3,), LABEL_IDS["foliage"])
    clip = gt_clip_offsets(MotionParams.from_dict({"effects": {"leaf_flutter": {"amplitude": 0.0}}}),
                           means, anchors, labels)
    near = (clip[:, 0] - clip[:, 1]).norm(dim=1).max()
    far = (clip[:, 0] - clip[:, 2]).norm(dim=1).max()
    assert float(near) < 0.05 * float(far)
    wind = torch.tensor([math.cos(math.radians(p.wind_dir_deg)), math.sin(math.radians(p.wind_dir_deg))])
    along = (clip[:, 0, :2] @ wind).abs().mean()
    across = (clip[:, 0, :2] @ torch.stack([-wind[1], wind[0]])).abs().mean()
    assert float(along) > 1.5 * float(across)


def test_motion_params_json_roundtrip_and_errors():
    p = MotionParams.from_dict({"wind_dir_deg": 75, "frames": 33,
                                "effects": {"grass_wave": {"amplitude": 0.05, "cycles": 3}}})
    d = json.loads(json.dumps(p.to_dict()))
    q = MotionParams.from_dict(d)
    assert q.to_dict() == p.to_dict()
    assert q.effects["grass_wave"].cycles == 3 and q.effects["foliage_sway"].cycles == 1
    assert set(d["effects"]) == set(EFFECT_TYPES)
    with pytest.raises(ValueError, match="gusts"):
        MotionParams.from_dict({"gusts": 2})
    with pytest.raises(ValueError, match="tornado"):
        MotionParams.from_dict({"effects": {"tornado": {}}})
    with pytest.raises(ValueError, match="wobble"):
        MotionParams.from_dict({"effects": {"flower_bob": {"wobble": 1}}})
    with pytest.raises(ValueError, match="frames"):
        MotionParams.from_dict({"frames": 1})


# ---- config -------------------------------------------------------------------------
def test_demo_yaml_matches_synth_config():
    doc = yaml.safe_load((ROOT / "config/scenes/demo.yaml").read_text())
    assert doc["name"] == "demo" and doc["source"] == "synthetic"
    assert doc["effects"] == list(EFFECT_TYPES)
    cfg = SynthConfig.from_dict(doc["synthetic"])
    assert cfg.to_dict() == SynthConfig.from_dict(cfg.to_dict()).to_dict()
    with pytest.raises(ValueError, match="colour"):
        SynthConfig.from_dict({**doc["synthetic"], "colour": 1})
    with pytest.raises(ValueError, match="num_images"):
        SynthConfig.from_dict({"capture": {"num_images": 2}})


# ---- capture ------------------------------------------------------------------------
def test_camera_path_is_casual_walkable_and_overlapping(scene):
    cams = camera_path(CameraPathConfig(), seed=0)
    assert len(cams) == 48 and len({c.name for c in cams}) == 48
    centers = np.array([c.center for c in cams])
    assert (np.abs(centers[:, 0]) < 5.5).all() and (centers[:, 1] > -5.0).all() and (centers[:, 1] < 4.0).all()
    assert (np.abs(centers[:, 2] - 1.6) < 0.3).all()
    fwd = np.array([c.forward for c in cams])
    assert (fwd[:, 2] < 0).all() and (fwd[:, 2] > -0.6).all()  # looking slightly down at the scene
    step = np.linalg.norm(np.diff(centers, axis=0), axis=1)
    turn = np.degrees(np.arccos(np.clip((fwd[1:] * fwd[:-1]).sum(1), -1, 1)))
    assert np.median(step) < 0.8 and np.median(turn) < 15  # neighbours overlap
    rolls = np.degrees(np.arcsin([c.R[0, 2] for c in cams]))  # camera x-axis tilt out of the horizontal
    assert 0.3 < np.std(rolls) < 5  # hand-held jitter, not a perfect rig, not a tumbling camera
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(scene.means.numpy()).query(centers)
    assert dist.min() > 0.5  # no Gaussian right in front of the lens (no blown-up splats)
    again = camera_path(CameraPathConfig(), seed=0)
    assert all(np.array_equal(a.viewmat, b.viewmat) for a, b in zip(cams, again))


def test_capture_images_are_textured_and_without_holes(scene):
    import cv2

    cams = camera_path(CameraPathConfig(), seed=0)
    sift = cv2.SIFT_create()
    for cam in (cams[0], cams[16], cams[24], cams[40]):
        img = render_image(scene, cam)
        gray = cv2.cvtColor((img * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2GRAY)
        assert len(sift.detect(gray, None)) >= 150, cam.name
        with torch.no_grad():
            _, alpha, _ = render_gaussians(scene, cam)
        # pixels whose ray meets the courtyard floor must be covered (no sky showing through)
        u, v = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
        rays = np.stack([(u - cam.K[0, 2]) / cam.K[0, 0], (v - cam.K[1, 2]) / cam.K[1, 1], np.ones_like(u)], -1) @ cam.R
        tz = -cam.center[2] / np.minimum(rays[..., 2], -1e-9)
        hit = cam.center[:2] + tz[..., None] * rays[..., :2]
        floor = (rays[..., 2] < -0.01) & (np.abs(hit[..., 0]) < 6.3) & (hit[..., 1] > -5.3) & (hit[..., 1] < 5.0)
        assert floor.sum() > 0.3 * floor.size
        assert float((alpha.numpy()[floor] < 0.9).mean()) < 0.01, cam.name
        assert img.max() < 0.99  # nothing blown out


def test_write_capture_files_roundtrip_and_determinism(tmp_path, small_cfg):
    out1, out2 = tmp_path / "a", tmp_path / "b"
    (out1 / "images").mkdir(parents=True)
    (out1 / "images" / "img_999.png").write_bytes(b"stale")
    from anigs.stages.capture import Outputs as CaptureOutputs

    summary = write_capture(small_cfg, CaptureOutputs(out1))
    write_capture(small_cfg, CaptureOutputs(out2))
    import imageio.v2 as imageio

    names = sorted(p.name for p in (out1 / "images").glob("*.png"))
    assert names == sorted(summary["images"]) and len(names) == 6  # stale image removed
    for name in names:
        a, b = imageio.imread(out1 / "images" / name), imageio.imread(out2 / "images" / name)
        assert a.shape == (72, 96, 3) and a.dtype == np.uint8 and a.std() > 5
        assert np.array_equal(a, b)
    gt = out1 / "gt"
    cams = load_cameras(gt / "cameras.json")
    assert [c.name for c in cams] == names and all((c.width, c.height) == (96, 72) for c in cams)
    g = build_scene(small_cfg.scene, small_cfg.seed)
    labels, anchors = np.load(gt / "labels.npy"), np.load(gt / "anchors.npy")
    assert labels.shape == (g.num,) and anchors.shape == (g.num, 3)
    assert np.array_equal(labels, g.extras["label"].numpy()) and np.array_equal(anchors, g.extras["anchor"].numpy())
    ply = load_ply(gt / "gaussians.ply")
    for k, v in g.params().items():
        assert torch.allclose(ply.params()[k], v, atol=1e-6), k
    motion = json.loads((gt / "motion.json").read_text())
    assert MotionParams.from_dict(motion["params"]).to_dict() == small_cfg.motion.to_dict()
    assert motion["effect_types"] == list(EFFECT_TYPES)
    assert motion["label_motion_class"]["building"] == "static"
    assert motion["label_effects"]["foliage"] == ["foliage_sway", "leaf_flutter"]
    scene_json = json.loads((gt / "scene.json").read_text())
    assert SynthConfig.from_dict(scene_json["config"]).to_dict() == small_cfg.to_dict()
    assert not list(out1.rglob(".*.tmp*"))  # atomic writes left no temporaries


# ---- CLI ----------------------------------------------------------------------------
def test_cli_capture_synthetic_and_photos(tmp_path, small_cfg):
    from anigs.cli import main

    out = tmp_path / "cap"
    assert main(["capture", "--params", json.dumps(small_cfg.to_dict()), "--out", str(out)]) == 0
    assert len(list((out / "images").glob("*.png"))) == 6 and (out / "gt" / "motion.json").exists()
    assert main(["capture", "--params", '{"sceen": {}}', "--out", str(tmp_path / "bad")]) == 1
    assert main(["capture", "--source", "photos", "--out", str(tmp_path / "p")]) == 1  # no --photos
    photos = tmp_path / "photos"
    photos.mkdir()
    import imageio.v2 as imageio

    rng = np.random.default_rng(0)
    for i in range(3):
        imageio.imwrite(photos / f"p{i}.png", rng.integers(0, 255, (60, 80, 3), dtype=np.uint8))
    assert main(["capture", "--source", "photos", "--photos", str(photos), "--params", '{"max_side": 40}',
                 "--out", str(tmp_path / "p")]) == 0
    got = sorted((tmp_path / "p" / "images").glob("*.png"))
    assert len(got) == 3 and max(imageio.imread(got[0]).shape[:2]) == 40
    assert main(["capture", "--source", "photos", "--photos", str(photos), "--params", '{"max_sid": 4}',
                 "--out", str(tmp_path / "p")]) == 1


# ---- optional pond and bare courtyard ------------------------------------------------------
def test_default_garden_has_no_water_and_unchanged_tables():
    g = build_scene(SceneConfig(num_gaussians=6000), 3)
    assert not bool((g.extras["label"] == WATER_LABEL).any())
    tables = motion_tables()
    assert "water" not in tables["label_effects"] and str(WATER_LABEL) not in tables["labels"]
    assert "water_ripple" not in MotionParams().to_dict()["effects"]
    assert tables["effect_types"] == list(EFFECT_TYPES)


def test_pond_scene_labels_geometry_and_tables():
    a = build_scene(SceneConfig(num_gaussians=6000, pond=True), 3)
    b = build_scene(SceneConfig(num_gaussians=6000, pond=True), 3)
    assert torch.equal(a.means, b.means) and torch.equal(a.extras["label"], b.extras["label"])
    labels = a.extras["label"]
    water = labels == WATER_LABEL
    assert int(water.sum()) > 100
    z = a.means[water, 2]
    assert float(z.max()) < 0.0 and float(z.min()) > -0.05  # flat, just under the lawn
    from anigs.synth.pond import RIM, in_pond
    xy = a.means[:, :2].numpy()
    assert bool(in_pond(xy[water.numpy()], 0.02).all())
    ground = (labels == LABEL_IDS["ground"]).numpy()
    assert not in_pond(xy[ground], RIM * 0.9).any()  # the lawn is carved out
    for name in ("grass", "trunk", "foliage"):
        assert not in_pond(xy[(labels == LABEL_IDS[name]).numpy()]).any(), name
    tables = motion_tables(water=True)
    assert tables["labels"][str(WATER_LABEL)] == "water" and tables["label_effects"]["water"] == ["water_ripple"]
    assert WATER_LABEL in tables["movable_labels"] and "water_ripple" in tables["effect_types"]


def test_pond_ripples_loop_and_stay_small():
    g = build_scene(SceneConfig(num_gaussians=6000, pond=True), 3)
    p = MotionParams()
    labels, anchors = g.extras["label"], g.extras["anchor"]
    off = gt_clip_offsets(p, g.means, anchors, labels)
    water = labels == WATER_LABEL
    assert float(off[0].abs().max()) == 0.0
    w = off[:, water]
    assert float(w[..., 2].abs().max()) > 0.005 and float(w.norm(dim=-1).max()) < 0.06
    nxt = gt_offsets(p, g.means, anchors, labels, float(p.frames))
    assert torch.allclose(nxt, off[0], atol=1e-5)
    custom = MotionParams.from_dict({"effects": {"water_ripple": {"amplitude": 0.0}}})
    assert float(gt_clip_offsets(custom, g.means, anchors, labels)[:, water].abs().max()) == 0.0


def test_courtyard_is_bare_and_still():
    a = build_scene(SceneConfig(num_gaussians=6000, layout="courtyard"), 4)
    b = build_scene(SceneConfig(num_gaussians=6000, layout="courtyard"), 4)
    assert torch.equal(a.means, b.means)
    labels = a.extras["label"]
    assert set(torch.unique(labels).tolist()) == {LABEL_IDS["ground"], LABEL_IDS["building"], LABEL_IDS["clutter"]}
    assert 0.85 * 6000 <= a.num <= 1.2 * 6000
    off = gt_clip_offsets(MotionParams(), a.means, a.extras["anchor"], labels)
    assert float(off.abs().max()) == 0.0
    cam = camera_path(CameraPathConfig(num_images=4, width=64, height=48), 4)[0]
    assert render_image(a, cam).std() > 0.02


def test_scene_layout_options_are_checked():
    with pytest.raises(ValueError, match="layout"):
        SceneConfig(layout="jungle")
    with pytest.raises(ValueError, match="pond"):
        SceneConfig(layout="courtyard", pond=True)
    assert SceneConfig.from_dict({"pond": True}).pond
    with pytest.raises(ValueError, match="pond"):
        SceneConfig.from_dict({"pond": "yes"})
