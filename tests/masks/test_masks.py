"""Dynamic-region masks (anigs.masks: vegetation, labels, sam2 backends; `anigs masks`)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from anigs.images import read_mask_png, write_mask_png
from anigs.masks import Frame, compute_masks, get_mask_backend, mask_iou, render_frames
from anigs.pixels import check_image, overlay
from anigs.geometry.ground import GroundPlane, ground_plane, pixel_heights
from anigs.masks.vegetation import VegetationConfig, otsu_threshold, vegetation_mask
from tests.masks.test_lift import SKY, toy_scene
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.effects import Outputs as EffectsOutputs


def _synthetic_frame(seed: int = 0, h: int = 96, w: int = 128):
    """Sky on top, grey textured wall on the left, brown ground, a textured green bush (returned mask)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    img[: h // 3] = SKY
    img[h // 3:] = np.array([0.45, 0.33, 0.2]) * rng.uniform(0.8, 1.2, (h - h // 3, w, 1))
    img[h // 4: 3 * h // 4, : w // 4] = np.array([0.55, 0.55, 0.56]) * rng.uniform(0.85, 1.15, (h // 2, w // 4, 1))
    yy, xx = np.mgrid[:h, :w]
    bush = ((yy - h * 0.55) / (h * 0.22)) ** 2 + ((xx - w * 0.62) / (w * 0.18)) ** 2 < 1
    leaves = np.array([0.18, 0.5, 0.14]) * rng.uniform(0.5, 1.4, (h, w, 1)) + rng.normal(0, 0.02, (h, w, 3))
    img[bush] = np.clip(leaves[bush], 0, 1)
    return img, bush


def test_vegetation_finds_the_bush():
    img, bush = _synthetic_frame()
    m = vegetation_mask(img)
    assert mask_iou(m, bush) >= 0.9
    # uint8 input gives the same mask
    m8 = vegetation_mask((img * 255 + 0.5).astype(np.uint8))
    assert mask_iou(m, m8) >= 0.98


@pytest.mark.parametrize("kind", ["sky", "wall", "black", "white"])
def test_vegetation_empty_on_sky_or_wall(kind):
    rng = np.random.default_rng(1)
    h, w = 60, 80
    if kind == "sky":
        img = np.tile(np.asarray(SKY, np.float32), (h, w, 1)) * rng.uniform(0.95, 1.05, (h, w, 1))
    elif kind == "wall":
        img = np.float32(0.5) * rng.uniform(0.7, 1.3, (h, w, 1)) * np.ones((1, 1, 3), np.float32)
    elif kind == "black":
        img = np.zeros((h, w, 3), np.float32)
    else:
        img = np.ones((h, w, 3), np.float32)
    for cfg in (VegetationConfig(), VegetationConfig(open_radius=1, close_radius=2, texture_weight=0.5)):
        m = vegetation_mask(np.clip(img, 0, 1), cfg)
        assert m.shape == (h, w) and not m.any()


def test_nan_frame_is_an_error():
    img, _ = _synthetic_frame()
    img[5, 7, 1] = np.nan
    with pytest.raises(ValueError, match=r"NaN.*x=7, y=5"):
        vegetation_mask(img, name="v03")
    with pytest.raises(ValueError, match="NaN"):
        compute_masks("vegetation", [Frame(img, name="v03")])
    with pytest.raises(ValueError, match="RGB image"):
        check_image(np.zeros((4, 4)))


def test_wrong_size_mask_is_an_error():
    img, _ = _synthetic_frame(h=48, w=64)

    def bad(frame):
        return {"dynamic": np.zeros((24, 32), bool)}

    with pytest.raises(ValueError, match=r"32x24.*64x48"):
        compute_masks(bad, [Frame(img, name="v00")])
    with pytest.raises(RuntimeError, match="no 'dynamic'"):
        compute_masks(lambda f: {"foliage": np.zeros((48, 64), bool)}, [Frame(img)])


def test_registry_and_config_errors():
    with pytest.raises(ValueError, match="unknown mask backend 'segformer'"):
        get_mask_backend("segformer")
    with pytest.raises(ValueError, match="unknown key"):
        VegetationConfig.from_dict({"treshold": 0.1})
    backend = get_mask_backend("vegetation", config={"min_area": 0.0})
    img, bush = _synthetic_frame()
    assert mask_iou(backend(Frame(img))["dynamic"], bush) >= 0.9


def test_otsu_between_modes():
    rng = np.random.default_rng(0)
    v = np.concatenate([rng.normal(-0.2, 0.03, 500), rng.normal(0.5, 0.05, 300)])
    t = otsu_threshold(v)
    member = np.arange(len(v)) >= 500
    assert ((v > t) == member).mean() >= 0.99 and -0.2 < t < 0.5
    assert otsu_threshold(np.full(10, 0.3)) is None


def test_mask_png_roundtrip_and_overlay(tmp_path):
    img, bush = _synthetic_frame()
    write_mask_png(tmp_path / "m.png", bush)
    assert (read_mask_png(tmp_path / "m.png") == bush).all()
    ov = overlay(img, bush)
    assert ov.shape == img.shape and not np.allclose(ov[bush], img[bush])
    left = ~bush & (np.arange(bush.shape[1])[None] < 5)  # far from the mask outline
    assert np.allclose(ov[left], img[left])


@pytest.fixture(scope="module")
def lawn_scene():
    gs, lab, cams = toy_scene(lawn=True, ring=6)
    frames = render_frames(gs, cams, SKY)
    return gs, lab, cams, frames


def test_labels_backend_effects_and_union(lawn_scene):
    gs, lab, cams, frames = lawn_scene
    eff = {"foliage_sway": [4], "wall_shake": [1]}
    out = compute_masks("labels", frames, gaussians=gs, labels=lab, effects=eff)
    for res in out:
        assert set(res) == {"foliage_sway", "wall_shake", "dynamic"}
        union = res["foliage_sway"] | res["wall_shake"]
        assert not (union & ~res["dynamic"]).any()  # dynamic contains every effect
        assert (res["dynamic"] & ~union).sum() <= 0.02 * union.sum() + 5  # (+ mixed boundary pixels)
        assert not (res["foliage_sway"] & res["wall_shake"]).any()
    assert all(res["foliage_sway"].any() for res in out[2:])  # views not blocked by the wall
    assert out[0]["wall_shake"].mean() > out[0]["foliage_sway"].mean()  # c00 looks at the wall
    with pytest.raises(ValueError, match="labels"):
        compute_masks("labels", frames[:1], gaussians=gs, labels=lab[:-1], dynamic_labels=[4])


def test_ground_cue_separates_lawn_from_bushes(lawn_scene):
    """On a lawn-green ground, colour alone marks the lawn; the ground cue removes it."""
    gs, lab, cams, frames = lawn_scene
    truth = compute_masks("labels", frames, gaussians=gs, labels=lab, dynamic_labels=[4])
    ground = ground_plane(gs.means.numpy(), np.array([0, 0, 1.0]), cams)
    assert abs(ground.offset) < 0.01 and ground.min_height > 0
    with_cue = compute_masks("vegetation", frames, ground=ground)
    without = compute_masks("vegetation", frames)
    keep = [k for k, t in enumerate(truth) if t["dynamic"].any()]  # c00 only sees the wall
    assert len(keep) >= 4
    iou_cue = np.mean([mask_iou(with_cue[k]["dynamic"], truth[k]["dynamic"]) for k in keep])
    iou_no = np.mean([mask_iou(without[k]["dynamic"], truth[k]["dynamic"]) for k in keep])
    assert iou_cue >= 0.75, iou_cue
    assert iou_no < iou_cue - 0.2, (iou_no, iou_cue)


def test_pixel_heights_of_a_flat_ground():
    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    cam = Camera(intrinsics_from_fov(60, 32, 24), look_at((0, -3, 1.5), (0, 0, 0)), 32, 24)
    plane = GroundPlane(np.array([0, 0, 1.0]), 0.0, 0.05)
    # analytic depth of the plane z = 0 at each pixel
    xs, ys = np.meshgrid(np.arange(32) + 0.5, np.arange(24) + 0.5)
    rays = np.stack([xs, ys, np.ones_like(xs)], -1) @ np.linalg.inv(cam.K).T @ cam.R
    depth = -cam.center[2] / rays[..., 2]
    h = pixel_heights(depth, cam, plane)
    assert np.allclose(h, 0.0, atol=1e-9)


def _flower_bed_frame(h: int = 96, w: int = 128):
    """A lawn seen from 1.5 m (exact depth) with a bed of small colourful blossoms on it.

    Returns (Frame, GroundPlane with a 0.3 m measured layer, bool mask of the bed).
    """
    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    rng = np.random.default_rng(3)
    cam = Camera(intrinsics_from_fov(60, w, h), look_at((0, -3, 1.5), (0, 0, 0)), w, h, "bed")
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    rays = np.stack([xs, ys, np.ones_like(xs)], -1) @ np.linalg.inv(cam.K).T @ cam.R
    depth = -cam.center[2] / rays[..., 2]
    img = (np.array([0.32, 0.42, 0.17]) * rng.uniform(0.85, 1.15, (h, w, 1))).astype(np.float32)
    bed = np.zeros((h, w), bool)
    bed[60:76, 30:90] = True
    colours = np.array([[0.9, 0.2, 0.2], [0.95, 0.85, 0.2], [0.85, 0.3, 0.8], [0.95, 0.95, 0.95]], np.float32)
    for y in range(61, 75, 4):
        for x in range(31 + (y % 3), 89, 4):
            img[y:y + 2, x:x + 2] = colours[rng.integers(len(colours))]
    plane = GroundPlane(np.array([0, 0, 1.0]), 0.0, 0.05, layer=0.3, camera_height=1.5)
    frame = Frame(img, cam, depth.astype(np.float32), np.ones((h, w), np.float32), "bed", np.asarray(SKY, np.float32))
    return frame, plane, bed


def test_flower_bed_inside_the_ground_layer():
    """Height cannot tell a flower bed from a thick fitted lawn, colour can: the bed is kept, the lawn not."""
    frame, plane, bed = _flower_bed_frame()
    m = vegetation_mask(frame.image, VegetationConfig(), frame=frame, ground=plane)
    assert mask_iou(m, bed) >= 0.7, mask_iou(m, bed)
    assert (m & ~bed).sum() <= 0.01 * (~bed).sum()  # the lawn around it stays static
    # the blossoms alone (no closing into beds) are specks that the small-component removal drops
    specks = vegetation_mask(frame.image, VegetationConfig(flower_bed_radius=0), frame=frame, ground=plane)
    assert specks.sum() < 0.5 * m.sum()
    # the old rule (flowers only above the ground layer): nothing
    assert not vegetation_mask(frame.image, VegetationConfig(flowers_in_ground=False), frame=frame, ground=plane).any()
    # without the blossoms the lawn gives an empty mask
    lawn = Frame(np.where(bed[..., None], frame.image[5:6, 5:6], frame.image), frame.camera, frame.depth,
                 frame.alpha, "lawn", frame.background)
    assert not vegetation_mask(lawn.image, VegetationConfig(), frame=lawn, ground=plane).any()


def _ring(n: int = 6, height: float = 1.6):
    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    K = intrinsics_from_fov(60, 32, 24)
    return [Camera(K, look_at((4 * np.cos(a), 4 * np.sin(a), height), (0, 0, 0.5)), 32, 24, f"c{i}")
            for i, a in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False))]


def _ground_and_bushes(noise: float, seed: int = 0, extra: np.ndarray | None = None) -> np.ndarray:
    """Centres of a ground layer at z = 0 scattered by ``noise`` (m, std) and bushes 0.4-1.5 m up."""
    rng = np.random.default_rng(seed)
    ground = np.c_[rng.uniform(-5, 5, (4000, 2)), rng.normal(0, noise, 4000) if noise > 0 else np.zeros(4000)]
    bushes = np.c_[rng.uniform(-3, 3, (600, 2)), rng.uniform(0.4, 1.5, 600)]
    return np.concatenate([ground, bushes] + ([extra] if extra is not None else []))


def test_estimate_ground_measures_the_ground_layer():
    """The layer is measured below the plane (nothing real is under the ground) and mirrored up."""
    cams, up = _ring(), np.array([0, 0, 1.0])
    clean = ground_plane(_ground_and_bushes(0.0), up, cams)
    assert abs(clean.offset) < 0.01 and clean.layer < 0.01
    assert clean.camera_height == pytest.approx(1.6, abs=0.01)
    assert clean.cut_height() == clean.min_height == pytest.approx(0.03 * clean.camera_height)
    for sigma in (0.05, 0.1):
        gp = ground_plane(_ground_and_bushes(sigma), up, cams)
        expect = 2.17 * sigma  # 97th percentile of |N(0, sigma)|
        assert abs(gp.offset) < 0.2 * sigma and abs(gp.layer - expect) < 0.2 * expect, (gp, expect)
        assert gp.cut_height() == pytest.approx(gp.layer)
        assert gp.cut_height(layer_scale=0.0) == gp.min_height  # the fixed margin only
        assert set(gp.to_dict()) >= {"normal", "offset", "min_height", "layer", "camera_height"}
    # a hopeless ground (scattered by half the camera height) is capped at 0.3 x camera height
    wild = ground_plane(_ground_and_bushes(0.5), up, cams)
    assert wild.cut_height() == pytest.approx(0.3 * wild.camera_height)
    # things far under the ground (a reflection in a pond) are not ground noise
    pond = np.c_[np.random.default_rng(1).uniform(-1, 1, (300, 2)), np.full(300, -1.5)]
    assert ground_plane(_ground_and_bushes(0.0, extra=pond), up, cams).layer < 0.01
    with pytest.raises(ValueError, match="layer_quantile"):
        ground_plane(_ground_and_bushes(0.0), up, cams, layer_quantile=1.0)
    with pytest.raises(ValueError, match="ground_layer"):
        VegetationConfig(ground_layer=-1.0)


@pytest.fixture(scope="module")
def noisy_lawn_scene():
    """The lawn scene with a badly fitted ground: splats scattered +-8 cm in height and tilted."""
    gs, lab, cams = toy_scene(lawn=True, ring=6, ground_noise=0.08)
    return gs, lab, cams, render_frames(gs, cams, SKY)


def test_ground_layer_removes_a_noisy_lawn(noisy_lawn_scene):
    """A green ground that renders above the fixed margin is removed; the bushes on it stay."""
    gs, lab, cams, frames = noisy_lawn_scene
    truth = compute_masks("labels", frames, gaussians=gs, labels=lab, dynamic_labels=[4])
    lawn = compute_masks("labels", frames, gaussians=gs, labels=lab, dynamic_labels=[0])
    ground = ground_plane(gs.means.numpy(), np.array([0, 0, 1.0]), cams)
    assert ground.layer > 2 * ground.min_height  # the scatter was measured
    keep = [k for k, t in enumerate(truth) if t["dynamic"].any()]
    assert len(keep) >= 4

    def scores(masks):
        iou = np.mean([mask_iou(masks[k]["dynamic"], truth[k]["dynamic"]) for k in keep])
        recall = np.mean([(masks[k]["dynamic"] & truth[k]["dynamic"]).sum() / truth[k]["dynamic"].sum()
                          for k in keep])
        leak = sum((m["dynamic"] & l["dynamic"]).sum() for m, l in zip(masks, lawn)) / sum(
            l["dynamic"].sum() for l in lawn)
        return iou, recall, leak

    iou, recall, leak = scores(compute_masks("vegetation", frames, ground=ground))
    assert iou >= 0.75 and recall >= 0.95 and leak <= 0.15, (iou, recall, leak)
    # the fixed margin alone (the old cue) lets most of the lawn in
    iou0, _, leak0 = scores(compute_masks("vegetation", frames, ground=ground, config={"ground_layer": 0.0}))
    assert leak0 >= 0.5 and iou0 < iou - 0.3, (iou0, leak0)


def test_appearance_labels_follow_what_a_gaussian_shows(lawn_scene):
    """A fitted Gaussian takes the label of what it depicts, not of its nearest labelled neighbour."""
    import torch

    from anigs.gaussians import Gaussians
    from anigs.render.labels import appearance_labels, render_label_map, transfer_labels

    gs, lab, cams, _ = lawn_scene
    # the labelled set itself: its own labels (hidden Gaussians fall back to nearest neighbour)
    same, weights, classes = appearance_labels(gs, gs, lab, cams)
    assert classes[0] == -1 and weights.shape == (gs.num, len(classes))
    assert (same == lab).mean() >= 0.95
    lmap = render_label_map(gs, lab, cams[3])
    assert lmap.shape == (cams[3].height, cams[3].width) and (lmap == -1).any() and (lmap == 4).any()
    # a floater 1 m in front of the camera, on its line of sight to a blob: its nearest
    # labelled Gaussian is the ground below it, but in that view it shows the blob
    cam = cams[3]
    blob = gs.means.numpy()[lab == 4].astype(np.float64)
    target = blob[np.argmin(np.linalg.norm(blob - cam.center, axis=1))]
    ray = (target - cam.center) / np.linalg.norm(target - cam.center)
    p = torch.tensor(cam.center + 1.0 * ray, dtype=torch.float32)[None]
    floater = Gaussians.from_points(p, torch.tensor([[0.3, 0.45, 0.16]]), 0.03, opacity=0.9)
    fitted = Gaussians.from_points(torch.cat([gs.means, p]), torch.zeros(gs.num + 1, 3), 0.01)
    fitted.log_scales = torch.cat([gs.log_scales, floater.log_scales])
    fitted.opacity_logits = torch.cat([gs.opacity_logits, floater.opacity_logits])
    assert transfer_labels(gs.means.numpy(), lab, p.numpy())[0] != 4
    got, _, _ = appearance_labels(fitted, gs, lab, [cam])
    assert got[-1] == 4
    with pytest.raises(ValueError, match="labels"):
        appearance_labels(fitted, gs, lab[:-1], [cam])


def test_sam2_backend_reports_what_to_install(tmp_path):
    """Where sam2 cannot import, building the backend raises ImportError naming the install step."""
    try:
        import sam2  # noqa: F401
        import torchvision  # noqa: F401
        importable = True
    except Exception:
        importable = False
    ckpt = tmp_path / "sam2.pt"
    ckpt.write_bytes(b"not a checkpoint")
    if importable:
        pytest.skip("sam2 imports here: the missing-dependency path cannot be exercised")
    with pytest.raises(ImportError, match="SAM2_BUILD_CUDA=0 pip install"):
        get_mask_backend("sam2", checkpoint=str(ckpt))
    with pytest.raises(FileNotFoundError, match="checkpoint not found"):
        get_mask_backend("sam2", checkpoint=str(tmp_path / "missing.pt"))


def test_sam2_random_weights_real_code_path():
    """SAM2 with random weights built offline from its config, on the real code path."""
    try:
        import sam2  # noqa: F401
        import torchvision  # noqa: F401
    except Exception as exc:  # torchvision on PyPI is a CUDA build: fails with the CPU torch
        pytest.skip(f"sam2 cannot import here ({type(exc).__name__}: {exc}); "
                    "needs sam2 + a torchvision matching torch (see NOTES.md)")
    img, bush = _synthetic_frame(h=64, w=64)
    backend = get_mask_backend("sam2", checkpoint=None, random_weights=True, points_per_side=4, device="cpu")
    out = compute_masks(backend, [Frame(img, name="v00")])
    assert out[0]["dynamic"].shape == (64, 64)


def test_cli_masks_with_labels(tmp_path, lawn_scene):
    from anigs.cli import main
    from anigs.views import ViewsConfig, azimuth_deg, location_cameras

    gs, lab, cams, _ = lawn_scene
    gs.save_ply(tmp_path / "canonical.ply")
    np.save(tmp_path / "labels.npy", lab)
    motion = {"labels": {"0": "ground", "1": "building", "4": "foliage"},
              "label_effects": {"ground": [], "building": [], "foliage": ["foliage_sway", "leaf_flutter"]}}
    (tmp_path / "motion.json").write_text(json.dumps(motion))
    vcfg = ViewsConfig(width=80, height=60)
    views = []
    pos = cams[3].center  # a side not hidden behind the wall
    heading = float(azimuth_deg(-pos, np.array([0, 0, 1.0])))
    for i, cam in enumerate(location_cameras(pos, heading, np.array([0, 0, 1.0]), vcfg)):
        views.append({"id": f"v{i:02d}", "camera": cam.to_dict()})
    (tmp_path / "views.json").write_text(json.dumps({"views": views, "up": [0, 0, 1]}))
    out = tmp_path / "masks"
    args = ["masks", "--canonical", str(tmp_path / "canonical.ply"), "--views", str(tmp_path),
            "--out", str(out), "--labels", str(tmp_path / "labels.npy"), "--motion", str(tmp_path / "motion.json")]
    assert main(args + ["--params", json.dumps({"backend": "labels"})]) == 0
    for v in views:
        assert read_mask_png(MasksOutputs(out).path("mask", view=v["id"])).shape == (60, 80)
        assert MasksOutputs(out).exists("overlay", view=v["id"])
        assert MasksOutputs(out).exists("effect_mask", view=v["id"], effect="foliage_sway") and MasksOutputs(out).exists("effect_mask", view=v["id"], effect="leaf_flutter")
    info = MasksOutputs(out).report()
    assert info["iou_vs_labels"]["min"] == 1.0  # the labels backend is its own yardstick
    lv = info["lift_vs_labels"]
    assert lv["precision"] >= 0.7 and lv["recall"] >= 0.9, lv  # one location only: 3 views
    dyn = MasksOutputs(out).dynamic()
    assert dyn.shape == (gs.num,) and dyn.dtype == bool
    # the vegetation backend on the same views, compared with the labels
    veg_params = json.dumps({"backend": "vegetation"})
    assert main(args + ["--out", str(tmp_path / "veg"), "--params", veg_params]) == 0
    veg = MasksOutputs(tmp_path / "veg").report()
    assert veg["backend"] == "vegetation"
    assert veg["views"][0]["iou_vs_labels"] >= 0.5, veg["views"][0]  # the view facing the blobs
    assert all(v["fraction"] <= 0.05 for v in veg["views"][1:]), veg["views"]  # side views: lawn, sky
    assert veg["lift_vs_labels"]["precision"] >= 0.8, veg["lift_vs_labels"]
    # first frames given as PNGs (e.g. frame 0 of the rendered clips) instead of rendering
    from anigs.images import write_rgb_png

    for v in views:
        write_rgb_png(tmp_path / "frames" / f"{v['id']}.png", np.full((60, 80, 3), 0.5, np.float32))
    assert main(args + ["--out", str(tmp_path / "grey"), "--first-frames", str(tmp_path / "frames"), "--params", veg_params]) == 0
    assert not read_mask_png(MasksOutputs(tmp_path / "grey").path("mask", view="v00")).any()  # an all-grey frame: empty mask, no crash
    (tmp_path / "frames" / "v01.png").unlink()
    assert main(args + ["--out", str(tmp_path / "grey2"), "--first-frames", str(tmp_path / "frames"), "--params", veg_params]) == 1


def test_labels_across_frames_and_transfer(lawn_scene):
    """Labels of ground-truth Gaussians rendered from cameras of another (similarity) frame."""
    from anigs.sfm.align import Similarity
    from anigs.masks.labels_backend import LabelsBackend
    from anigs.render.labels import labels_for
    from anigs.sfm.align import align_cameras
    from scipy.spatial.transform import Rotation

    gs, lab, cams, frames = lawn_scene
    sim = Similarity(1.7, Rotation.from_euler("zyx", [30, 5, -3], degrees=True).as_matrix(), np.array([0.5, -2, 1]))
    rec_cams = [sim.apply_camera(c) for c in cams]  # the "reconstruction" frame
    est, rms = align_cameras(rec_cams, cams)  # reconstruction -> ground-truth frame
    assert rms < 1e-6 and est.scale == pytest.approx(1 / 1.7)
    direct = LabelsBackend(gs, lab, {"dynamic": [4]})
    across = LabelsBackend(gs, lab, {"dynamic": [4]}, to_gaussians_frame=est)
    for f, rc in zip(frames[2:4], rec_cams[2:4]):
        a = direct(f)["dynamic"]
        b = across(Frame(f.image, rc, name=f.name))["dynamic"]
        assert mask_iou(a, b) >= 0.98
    # nearest-neighbour transfer of the labels onto the Gaussians of the other frame
    rec_means = sim.apply(gs.means.numpy().astype(np.float64))
    gt_to_rec, _ = align_cameras(cams, rec_cams)
    moved = labels_for(rec_means, lab, gs.means.numpy(), gt_to_rec)
    assert (moved == lab).mean() >= 0.99


def test_cli_masks_lifts_over_capture_photos(tmp_path, lawn_scene):
    """``--images``: the capture photos are segmented too and the lifting votes over them; the
    queued views' masks are completed with the lifted set; the appearance yardstick is reported."""
    from anigs.cameras import save_cameras
    from anigs.cli import main
    from anigs.images import write_rgb_png
    from anigs.render.labels import dynamic_masks
    from anigs.views import ViewsConfig, azimuth_deg, location_cameras

    gs, lab, cams, frames = lawn_scene
    gs.save_ply(tmp_path / "canonical.ply")
    np.save(tmp_path / "labels.npy", lab)
    motion = {"labels": {"0": "ground", "1": "building", "4": "foliage"},
              "label_effects": {"ground": [], "building": [], "foliage": ["foliage_sway"]}}
    (tmp_path / "motion.json").write_text(json.dumps(motion))
    save_cameras(tmp_path / "cameras.json", cams)
    for fr in frames:  # the "photos": renders of the scene from the ring of capture cameras
        write_rgb_png(tmp_path / "images" / f"{fr.name}.png", fr.image)
    pos = cams[3].center
    heading = float(azimuth_deg(-pos, np.array([0, 0, 1.0])))
    vcams = location_cameras(pos, heading, np.array([0, 0, 1.0]), ViewsConfig(width=80, height=60))
    views = [{"id": f"v{i:02d}", "camera": c.to_dict()} for i, c in enumerate(vcams)]
    (tmp_path / "views.json").write_text(json.dumps({"views": views, "up": [0, 0, 1]}))
    base = ["masks", "--canonical", str(tmp_path / "canonical.ply"), "--views", str(tmp_path),
            "--labels", str(tmp_path / "labels.npy"), "--motion", str(tmp_path / "motion.json"),
            "--gt-gaussians", str(tmp_path / "canonical.ply"), "--gt-cameras", str(tmp_path / "cameras.json"),
            "--cameras", str(tmp_path / "cameras.json"),
            "--params", json.dumps({"backend": "vegetation", "appearance": True})]
    assert main(base + ["--out", str(tmp_path / "views_only")]) == 0
    assert main(base + ["--out", str(tmp_path / "capture"), "--images", str(tmp_path / "images")]) == 0
    before = MasksOutputs(tmp_path / "views_only").report()
    after = MasksOutputs(tmp_path / "capture").report()
    assert after["capture"]["images"] == len(cams) and after["lift"]["num_views"] == len(vcams) + len(cams)
    # one location sees one side of the blobs (the rest is guessed from neighbours: the wall and
    # lawn next to them come along); the ring of photos sees all of them
    assert after["lift"]["decided"] > before["lift"]["decided"] + 1000, (before["lift"], after["lift"])
    lb, la = before["lift_vs_labels"], after["lift_vs_labels"]
    assert la["precision"] >= lb["precision"] + 0.1 and la["precision"] >= 0.95 and la["recall"] >= 0.95, (lb, la)
    assert after["lift_vs_labels"]["recall"] >= 0.8 and after["lift_vs_labels"]["precision"] >= 0.8, after
    # appearance yardstick (here the labelled set is the canonical set itself)
    for info in (before, after):
        assert set(info["lift_appearance"]) >= {"precision", "recall", "num_appearance_dynamic"}
        assert all("iou_appearance" in v for v in info["views"]) and "iou_appearance" in info
    # every queued view's mask contains the pixels its lifted dynamic Gaussians dominate
    dyn = MasksOutputs(tmp_path / "capture").dynamic()
    for v, want in zip(views, dynamic_masks(gs, dyn, vcams)):
        got = read_mask_png(MasksOutputs(tmp_path / "capture").path("mask", view=v["id"]))
        assert not (want & ~got).any()
    assert len(after["completed_fraction"]) == len(views)
    # photos missing: an error naming the folder; --images without --cameras: an error
    assert main(base + ["--out", str(tmp_path / "x"), "--images", str(tmp_path / "nope")]) == 1
    no_cams = base[:base.index("--gt-gaussians")] + ["--params", json.dumps({"backend": "vegetation"})]
    assert main(no_cams + ["--out", str(tmp_path / "y"), "--images", str(tmp_path / "images")]) == 1


def test_one_mask_reader_for_every_mask_format(tmp_path):
    """read_mask: 0/255 and 0/1 PNGs, 16-bit PNGs, RGB PNGs and .npy arrays give the same soft mask."""
    import cv2

    from anigs.images import read_mask, read_mask_png

    m = np.zeros((6, 7), bool)
    m[2:4, 1:5] = True
    cv2.imwrite(str(tmp_path / "a.png"), m.astype(np.uint8) * 255)
    cv2.imwrite(str(tmp_path / "b.png"), m.astype(np.uint8))
    cv2.imwrite(str(tmp_path / "c.png"), m.astype(np.uint16) * 65535)
    cv2.imwrite(str(tmp_path / "d.png"), np.repeat(m[..., None].astype(np.uint8) * 255, 3, 2))
    np.save(tmp_path / "e.npy", m.astype(np.float32))
    for name in ("a.png", "b.png", "c.png", "d.png", "e.npy"):
        soft = read_mask(tmp_path / name)
        assert soft.dtype == np.float32 and soft.shape == m.shape, name
        np.testing.assert_array_equal(soft, m.astype(np.float32), err_msg=name)
        np.testing.assert_array_equal(read_mask_png(tmp_path / name), m, err_msg=name)
    half = np.full((2, 2), 128, np.uint8)
    cv2.imwrite(str(tmp_path / "s.png"), half)
    assert np.allclose(read_mask(tmp_path / "s.png"), 128 / 255)
    with pytest.raises(FileNotFoundError, match="nope.png"):
        read_mask(tmp_path / "nope.png")
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(ValueError, match="bad.png"):
        read_mask(tmp_path / "bad.png")


def test_cli_masks_effects_backend_renders_the_effects_stage_sets(tmp_path, lawn_scene):
    """The default backend: each chosen effect's Gaussians (effects stage) rendered per view; the
    dynamic set is the effects stage's own (not lifted again); nothing chosen, nothing masked."""
    from anigs.cli import main
    from anigs.effects.config import REGIONS
    from anigs.render.labels import dynamic_masks
    from anigs.views import ViewsConfig, azimuth_deg, location_cameras

    gs, lab, cams, _ = lawn_scene
    gs.save_ply(tmp_path / "canonical.ply")
    pos = cams[3].center
    heading = float(azimuth_deg(-pos, np.array([0, 0, 1.0])))
    vcams = location_cameras(pos, heading, np.array([0, 0, 1.0]), ViewsConfig(width=80, height=60))
    views = [{"id": f"v{i:02d}", "camera": c.to_dict()} for i, c in enumerate(vcams)]
    (tmp_path / "views.json").write_text(json.dumps({"views": views, "up": [0, 0, 1]}))
    eff = tmp_path / "effects"
    eff.mkdir()
    regions = np.where(lab == 4, REGIONS.index("foliage"), -1).astype(np.int8)  # the blobs are foliage
    np.save(EffectsOutputs(eff).path("regions"), regions)
    np.save(EffectsOutputs(eff).path("dynamic"), regions >= 0)
    EffectsOutputs(eff).path("effects").write_text(json.dumps({"chosen": ["foliage_sway", "leaf_flutter"]}))
    args = ["masks", "--canonical", str(tmp_path / "canonical.ply"), "--views", str(tmp_path),
            "--effects", str(eff), "--params", "{}"]
    assert main(args + ["--out", str(tmp_path / "m")]) == 0
    info = MasksOutputs(tmp_path / "m").report()
    assert info["backend"] == "effects" and info["lift"]["source"].startswith("effects:")
    np.testing.assert_array_equal(MasksOutputs(tmp_path / "m").dynamic(), regions >= 0)
    want = dynamic_masks(gs, regions >= 0, vcams)
    for v, w in zip(views, want):
        got = read_mask_png(MasksOutputs(tmp_path / "m").path("mask", view=v["id"]))
        assert got.any() == w.any() and (got & w).sum() >= 0.9 * w.sum(), v["id"]
        for e in ("foliage_sway", "leaf_flutter"):  # one mask per chosen effect
            assert MasksOutputs(tmp_path / "m").exists("effect_mask", view=v["id"], effect=e)
    labels = MasksOutputs(tmp_path / "m").effect_labels()  # each dynamic Gaussian's effect: foliage = 1
    np.testing.assert_array_equal(labels, np.where(regions >= 0, 1, 0))
    # a backend with one mask per view (vegetation) gets the per-effect masks too, within its own mask
    veg = args[:-2] + ["--params", json.dumps({"backend": "vegetation"}), "--out", str(tmp_path / "veg")]
    assert main(veg) == 0
    for v in views:
        whole = read_mask_png(MasksOutputs(tmp_path / "veg").path("mask", view=v["id"]))
        for e in ("foliage_sway", "leaf_flutter"):
            m = read_mask_png(MasksOutputs(tmp_path / "veg").path("effect_mask", view=v["id"], effect=e))
            assert not (m & ~whole).any(), (v["id"], e)
    assert any(read_mask_png(MasksOutputs(tmp_path / "veg").path("effect_mask", view=v["id"], effect="foliage_sway")).any() for v in views)
    EffectsOutputs(eff).path("effects").write_text(json.dumps({"chosen": []}))
    np.save(EffectsOutputs(eff).path("dynamic"), np.zeros(gs.num, bool))
    assert main(args + ["--out", str(tmp_path / "none")]) == 0
    assert not any(read_mask_png(MasksOutputs(tmp_path / "none").path("mask", view=v["id"])).any() for v in views)
    assert not MasksOutputs(tmp_path / "none").dynamic().any()
    assert main(args[:-4] + ["--params", "{}", "--out", str(tmp_path / "x")]) == 1  # no --effects: an error
