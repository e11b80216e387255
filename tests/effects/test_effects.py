"""Effect detection (anigs.effects): per-effect precision/recall on the synthetic garden, the garden
with a pond and the bare courtyard; flowers of any hue; green pictures on walls stay still.

The fitted model is the ground-truth scene itself (small scenes, few small photos), so the figures
measure the detector, not the static fit.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.effects import EFFECTS, REGIONS, EffectsConfig, detect_effects, save_overview
from anigs.effects import cues
from anigs.gaussians import Gaussians, rgb_to_sh0
from anigs.images import load_image as read_rgb_png
from anigs.render.labels import render_label_map
from anigs.synth import LABEL_IDS, CameraPathConfig, SceneConfig, build_scene, camera_path, render_image
from anigs.synth.scene import frame_from_normal, quat_from_matrix
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.synth.scene import SKY

TRUTH = {"foliage_sway": "foliage", "leaf_flutter": "foliage", "grass_wave": "grass", "flower_bob": "flowers",
         "water_ripple": "water"}


def _capture(scene_cfg: SceneConfig, images: int = 12, width: int = 160):
    g = build_scene(scene_cfg, 0)
    cams = camera_path(CameraPathConfig(num_images=images, width=width, height=width * 3 // 4), 0)
    return g, cams, [render_image(g, c) for c in cams]


def _precision_recall(res, g) -> dict[str, tuple[float, float]]:
    labels = g.extras["label"].numpy()
    out = {}
    for e, r in res.effects.items():
        truth = labels == LABEL_IDS[TRUTH[e]]
        pred = np.zeros(len(labels), bool)
        pred[r.indices] = True
        tp = int((pred & truth).sum())
        out[e] = (tp / max(int(pred.sum()), 1), tp / max(int(truth.sum()), 1))
    return out


def _pixel_iou(res, g, effect: str) -> float:
    labels = g.extras["label"].numpy()
    inter = union = 0
    for cam, m in zip(res.cameras, res.effects[effect].masks):
        t = render_label_map(g, labels, cam) == LABEL_IDS[TRUTH[effect]]
        inter += int((t & m).sum())
        union += int((t | m).sum())
    return inter / max(union, 1)


@pytest.fixture(scope="module")
def garden():
    g, cams, imgs = _capture(SceneConfig(num_gaussians=12000))
    return g, detect_effects(imgs, cams, g, EffectsConfig())


@pytest.fixture(scope="module")
def pond():
    g, cams, imgs = _capture(SceneConfig(num_gaussians=12000, pond=True))
    return g, detect_effects(imgs, cams, g, EffectsConfig())


def test_garden_detects_its_four_effects(garden):
    g, res = garden
    assert res.detected == ["foliage_sway", "leaf_flutter", "grass_wave", "flower_bob"]
    pr = _precision_recall(res, g)
    print("garden precision/recall:", {e: tuple(round(v, 3) for v in pr[e]) for e in EFFECTS})
    assert pr["foliage_sway"][0] >= 0.7 and pr["foliage_sway"][1] >= 0.85
    assert pr["grass_wave"][0] >= 0.7 and pr["grass_wave"][1] >= 0.4
    assert pr["flower_bob"][0] >= 0.6 and pr["flower_bob"][1] >= 0.2
    assert _pixel_iou(res, g, "foliage_sway") >= 0.7
    assert not res.effects["water_ripple"].detected and len(res.effects["water_ripple"].indices) == 0
    for e in EFFECTS:  # every decision comes with its figures and a sentence
        r = res.effects[e]
        assert 0.0 <= r.confidence <= 1.0 and r.reason and len(r.masks) == len(res.photos)
    assert "No water" in res.effects["water_ripple"].reason


def test_pond_water_region_matches_the_labels(pond):
    g, res = pond
    assert res.effects["water_ripple"].detected
    iou = _pixel_iou(res, g, "water_ripple")
    p, r = _precision_recall(res, g)["water_ripple"]
    print(f"pond water: pixel IoU {iou:.3f}, Gaussian precision {p:.3f} recall {r:.3f}")
    assert iou >= 0.7 and p >= 0.8 and r >= 0.7
    assert {"foliage_sway", "grass_wave", "flower_bob"} <= set(res.detected)


def test_bare_courtyard_has_no_effects(tmp_path):
    g, cams, imgs = _capture(SceneConfig(num_gaussians=12000, layout="courtyard"))
    res = detect_effects(imgs, cams, g, EffectsConfig())
    assert res.detected == [] and not res.dynamic().any()
    assert all(r.pixel_fraction < EffectsConfig().decide.min_pixel_fraction for r in res.effects.values())
    doc = json.loads(json.dumps(res.to_json()))  # the detection part of the stage's report
    assert set(doc["effects"]) == set(EFFECTS)
    for e in EFFECTS:
        assert {"detected", "pixel_fraction", "gaussian_fraction", "confidence", "reason"} <= set(doc["effects"][e])
        assert doc["effects"][e]["detected"] is False
    save_overview(tmp_path / "overview.png", res)
    assert read_rgb_png(tmp_path / "overview.png").shape[1] >= 4 * 200


def test_ground_scatter_hidden_under_the_lawn_leaves_grass_and_flowers(garden):
    """A fitted ground keeps Gaussians scattered deep under its surface (no photo sees them): they
    must not lift the ground cut over the lawn's grass tufts and the flower beds (the demo's fitted
    model lost both so: the centres' layer reached 0.36 m, above the grass height)."""
    g0, base = garden
    g, cams, imgs = _capture(SceneConfig(num_gaussians=12000))
    labels = g.extras["label"].numpy()
    rng = np.random.default_rng(3)
    pick = rng.choice(np.flatnonzero(labels == LABEL_IDS["ground"]), 2000)
    buried = g.subset(torch.from_numpy(pick))
    buried.means[:, 2] -= torch.from_numpy(rng.uniform(0.02, 0.45, len(pick))).float()
    buried.log_scales.sub_(math.log(2.0))  # smaller than the ground splats they hang under
    fitted = Gaussians.concat([g, buried])
    res = detect_effects(imgs, cams, fitted, EffectsConfig())  # the photos are the scene's: the tail is hidden
    plane = res.ground.plane
    assert plane is not None and plane.cut_height() > 0.2 * plane.camera_height  # the centres' layer is thick
    assert res.ground.cut_height() < 0.5 * EffectsConfig().regions.grass_max_height * plane.camera_height
    assert res.detected == ["foliage_sway", "leaf_flutter", "grass_wave", "flower_bob"]
    pr, pr0 = _precision_recall(res, fitted), _precision_recall(base, g0)
    print("with a buried ground tail:", {e: tuple(round(v, 3) for v in pr[e]) for e in EFFECTS})
    for e in ("grass_wave", "flower_bob"):
        assert pr[e][0] >= pr0[e][0] - 0.1 and pr[e][1] >= pr0[e][1] - 0.1, (e, pr[e], pr0[e])


# ---- small hand-built scenes ------------------------------------------------------------------
def _gaussians(means, scales, normals, colors, opacity=0.95, labels=None) -> Gaussians:
    n = len(means)
    q = quat_from_matrix(frame_from_normal(np.asarray(normals, float)))
    return Gaussians(
        means=torch.tensor(means, dtype=torch.float32), quats=torch.tensor(q, dtype=torch.float32),
        log_scales=torch.log(torch.tensor(scales, dtype=torch.float32)),
        opacity_logits=torch.logit(torch.full((n,), opacity)),
        sh=rgb_to_sh0(torch.tensor(np.clip(colors, 0.02, 0.97), dtype=torch.float32))[:, None, :].contiguous(),
        extras={"label": torch.tensor(labels if labels is not None else np.zeros(n), dtype=torch.int64)})


def _floor(rng, half: float, step: float, color) -> tuple:
    xy = np.stack(np.meshgrid(np.arange(-half, half, step), np.arange(-half, half, step)), -1).reshape(-1, 2)
    xy = xy + rng.uniform(-0.3, 0.3, xy.shape) * step
    m = len(xy)
    means = np.column_stack([xy, np.zeros(m)])
    cols = np.asarray(color) * rng.uniform(0.85, 1.15, (m, 1))
    return means, np.tile([0.8 * step, 0.8 * step, 0.003], (m, 1)), np.tile([0.0, 0, 1], (m, 1)), cols


def _ring_cameras(target, radius: float, height: float, count: int, arc: float = 2 * math.pi, start: float = 0.0,
                  size=(160, 120)) -> list[Camera]:
    K = intrinsics_from_fov(55.0, *size)
    cams = []
    for i in range(count):
        a = start + arc * i / count
        eye = np.array([target[0] + radius * math.cos(a), target[1] + radius * math.sin(a), height])
        cams.append(Camera(K, look_at(eye, target), size[0], size[1], f"c{i:02d}.png"))
    return cams


def bush_with_a_blossom():
    """A bush (green leaves on an ellipsoid shell) on a grey floor with a red blossom on its front, seen
    by 8 cameras: (Gaussians with labels 0 floor, 1 leaves, 2 blossom, cameras, their images)."""
    rng = np.random.default_rng(1)
    parts = [_floor(rng, 3.0, 0.08, (0.45, 0.4, 0.35)) + (0,)]
    # a bush: leaves on an ellipsoid shell, standing on the floor
    d = rng.normal(size=(2500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    leaves = np.array([0.0, 0, 0.75]) + d * rng.uniform(0.85, 1.0, (len(d), 1)) * [0.6, 0.6, 0.55]
    keep = leaves[:, 2] > 0.25
    leaves, d = leaves[keep], d[keep]
    green = np.array([0.2, 0.42, 0.12]) * rng.uniform(0.6, 1.3, (len(leaves), 1))
    parts.append((leaves, np.tile([0.05, 0.035, 0.006], (len(leaves), 1)), rng.normal(size=(len(leaves), 3)), green, 1))
    # a red blossom on the bush's front: a cluster of petals just outside the shell
    e = rng.normal(size=(500, 3))
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    head = np.array([0.0, -0.62, 0.95]) + e * rng.uniform(0.0, 0.14, (len(e), 1))
    red = np.array([0.85, 0.1, 0.08]) * rng.uniform(0.85, 1.1, (len(e), 1))
    parts.append((head, np.tile([0.025, 0.02, 0.005], (len(e), 1)), e, red, 2))
    g = _gaussians(*[np.concatenate([p[k] for p in parts]) for k in range(4)],
                   labels=np.concatenate([np.full(len(p[0]), p[4]) for p in parts]))
    cams = _ring_cameras((0.0, 0.0, 0.8), 2.6, 1.5, 8, arc=math.pi, start=-math.pi * 0.95)
    return g, cams, [render_image(g, c, SKY) for c in cams]


def test_red_flower_next_to_leaves_is_a_flower_not_foliage():
    g, cams, imgs = bush_with_a_blossom()
    res = detect_effects(imgs, cams, g, EffectsConfig())
    labels = g.extras["label"].numpy()
    flowers = np.isin(np.arange(g.num), res.effects["flower_bob"].indices)
    foliage = np.isin(np.arange(g.num), res.effects["foliage_sway"].indices)
    blossom, leaf = labels == 2, labels == 1
    print(f"blossom in flower_bob {flowers[blossom].mean():.3f}, in foliage {foliage[blossom].mean():.3f}; "
          f"leaves in foliage {foliage[leaf].mean():.3f}")
    assert res.effects["flower_bob"].detected and res.effects["foliage_sway"].detected
    assert flowers[blossom].mean() >= 0.6 and foliage[blossom].mean() <= 0.1
    assert foliage[leaf].mean() >= 0.7 and flowers[leaf].mean() <= 0.2


def test_green_picture_on_a_wall_is_not_foliage():
    rng = np.random.default_rng(2)
    floor = _floor(rng, 3.0, 0.08, (0.55, 0.52, 0.48))
    # a wall at y = 2 facing -y, with a textured green "landscape" picture 1.4 x 0.9 m on it
    ax, az = np.meshgrid(np.arange(-3.0, 3.0, 0.05), np.arange(0.0, 2.6, 0.05))
    ax, az = ax.ravel() + rng.uniform(-0.01, 0.01, ax.size), az.ravel() + rng.uniform(-0.01, 0.01, ax.size)
    wall = np.column_stack([ax, np.full(ax.size, 2.0), az])
    cols = np.tile([0.86, 0.83, 0.76], (ax.size, 1)) * rng.uniform(0.95, 1.05, (ax.size, 1))
    pic = (np.abs(ax - 0.2) < 0.7) & (np.abs(az - 1.45) < 0.45)
    tone = 0.75 + 0.5 * np.sin(7 * ax[pic]) * np.cos(5 * az[pic]) + rng.uniform(-0.2, 0.2, pic.sum())
    cols[pic] = np.column_stack([0.2 * tone, 0.5 * tone, 0.15 * tone])
    wall_parts = (wall, np.tile([0.035, 0.035, 0.003], (ax.size, 1)), np.tile([0.0, -1, 0], (ax.size, 1)), cols)
    labels = np.concatenate([np.zeros(len(floor[0])), np.where(pic, 1, 0)])
    g = _gaussians(*[np.concatenate([floor[k], wall_parts[k]]) for k in range(4)], opacity=0.98, labels=labels)
    cams = _ring_cameras((0.2, 2.0, 1.3), 3.0, 1.5, 6, arc=math.pi / 3, start=-math.pi / 2 - math.pi / 6)
    imgs = [render_image(g, c, SKY) for c in cams]
    cfg = EffectsConfig()
    # the picture is green by colour in every photo: only geometry can tell it from a plant
    pic_px = [render_label_map(g, labels, c) == 1 for c in cams]
    assert all(cues.green(im, cfg.regions.green_hue, cfg.regions.green_min_saturation, cfg.regions.min_value)[m].mean() > 0.5
               for im, m in zip(imgs, pic_px))
    res = detect_effects(imgs, cams, g, cfg)
    foliage = np.isin(np.arange(g.num), res.effects["foliage_sway"].indices)
    assert not res.effects["foliage_sway"].detected, res.effects["foliage_sway"].reason
    assert foliage[labels == 1].mean() < 0.05
    assert "flat vertical" in res.effects["foliage_sway"].reason


def test_stage_effects_list_restricts_and_reports_what_the_scene_lacks(tmp_path):
    """`anigs effects`: `requested: auto` simulates every detected effect; a list restricts it, and
    a listed effect that was not found is reported (requested_not_found), not simulated."""
    from anigs.cameras import save_cameras
    from anigs.cli import main
    from anigs.images import write_rgb_png
    from anigs.effects.choice import choose

    assert choose(["foliage_sway", "flower_bob"], "auto") == (["foliage_sway", "flower_bob"], [])
    assert choose(["foliage_sway"], ["flower_bob", "foliage_sway"]) == (["foliage_sway"], ["flower_bob"])
    with pytest.raises(ValueError, match="unknown effect"):
        choose([], ["wind_chimes"])
    g, cams, imgs = _capture(SceneConfig(num_gaussians=6000, pond=True), images=8, width=128)
    g.save_ply(tmp_path / "canonical.ply")
    save_cameras(tmp_path / "cameras.json", cams)
    for cam, img in zip(cams, imgs):
        write_rgb_png(tmp_path / "images" / cam.name, img)
    base = ["effects", "--canonical", str(tmp_path / "canonical.ply"), "--cameras", str(tmp_path / "cameras.json"),
            "--images", str(tmp_path / "images")]
    assert main(base + ["--out", str(tmp_path / "auto"), "--params", "{}"]) == 0
    auto = EffectsOutputs(tmp_path / "auto").report()
    assert auto["requested"] == "auto" and auto["chosen"] == auto["detected"] and "water_ripple" in auto["chosen"]
    listed = json.dumps({"requested": ["water_ripple", "grass_wave", "flower_bob"]})
    assert main(base + ["--out", str(tmp_path / "list"), "--params", listed]) == 0
    doc = EffectsOutputs(tmp_path / "list").report()
    want = [e for e in ("water_ripple", "grass_wave", "flower_bob") if e in auto["detected"]]
    assert doc["chosen"] == want and doc["requested_not_found"] == [e for e in ("water_ripple", "grass_wave",
                                                                                "flower_bob") if e not in want]
    regions = EffectsOutputs(tmp_path / "list").regions()
    dyn = EffectsOutputs(tmp_path / "list").dynamic()
    assert dyn.shape == (g.num,) and dyn.sum() == doc["num_dynamic"]
    assert dyn.sum() < EffectsOutputs(tmp_path / "auto").dynamic().sum()
    foliage = regions == REGIONS.index("foliage")
    assert not (dyn & foliage).any()  # foliage was not asked for: it stays still
    assert (tmp_path / "list" / "overview.png").stat().st_size > 0
