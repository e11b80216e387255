"""Structure from motion (anigs.sfm.colmap, anigs.sfm.align) on small rendered textured scenes.

The scene: flat textured Gaussians (random colours and brightness, 2-7 cm) on a ground
plane and on the faces of four boxes, rendered with the project's rasterizer at 320x240.
Two captures: a ring of 20 cameras around the boxes (SIMPLE_RADIAL, so the undistortion
path runs) and a forward-facing grid of 16 cameras with a small baseline (SIMPLE_PINHOLE).
"""
from __future__ import annotations

import logging
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pycolmap = pytest.importorskip("pycolmap")

from anigs.sfm import colmap as sfm_mod  # noqa: E402
from anigs.sfm import plan, steps  # noqa: E402
from anigs.sfm.align import (Similarity, pose_errors, rotation_angle_deg, rotation_between,  # noqa: E402
                         umeyama)
from anigs.geometry import estimate_up  # noqa: E402
from anigs.cameras import Camera, intrinsics_from_fov, load_cameras, look_at  # noqa: E402
from anigs.gaussians import Gaussians  # noqa: E402
from anigs.sfm.colmap import SfmConfig, SfmError, run_sfm  # noqa: E402
from anigs.sfm.fingerprint import database_fingerprints, model_fingerprint  # noqa: E402
from anigs.sfm.tracks import load_tracks  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402
from _captures import render as render_capture, textured_discs  # noqa: E402

W, H = 320, 240
def textured_scene(seed: int = 0, n_ground: int = 3000, n_box: int = 700) -> Gaussians:
    """Flat random-coloured Gaussians on the ground (z=0, 5 m) and on four boxes' faces."""
    boxes = [((-0.8, -0.5), (0.7, 0.6, 0.9)), ((0.9, 0.6), (0.5, 0.8, 0.5)),
             ((0.2, -1.2), (0.6, 0.4, 1.3)), ((-0.6, 1.1), (0.4, 0.4, 0.7))]
    return textured_discs(seed, 2.5, boxes, n_ground, n_box)


def ring_cameras(n: int = 20, seed: int = 0) -> list[Camera]:
    rng = np.random.default_rng(seed + 1)
    K = intrinsics_from_fov(60, W, H)
    cams = []
    for i in range(n):
        a = 2 * math.pi * i / n + 0.05 * rng.standard_normal()
        eye = [3.5 * math.cos(a), 3.5 * math.sin(a), 2.3 + 0.3 * rng.standard_normal()]
        cams.append(Camera(K, look_at(eye, [0, 0, 0.3]), W, H, f"ring_{i:03d}.png"))
    return cams


def forward_cameras(n: int = 16, spread: float = 0.15, seed: int = 0) -> list[Camera]:
    """A hand-held forward-facing capture: small baseline, all cameras facing +y."""
    rng = np.random.default_rng(seed + 2)
    K = intrinsics_from_fov(60, W, H)
    cams = []
    for i in range(n):
        dx, dz = rng.uniform(-spread, spread, 2)
        target = np.array([0, 0, 0.3]) + 0.1 * rng.standard_normal(3)
        cams.append(Camera(K, look_at([dx, -3.5, 1.6 + dz], target), W, H, f"ff_{i:03d}.png"))
    return cams


@pytest.fixture(scope="module")
def scene() -> Gaussians:
    return textured_scene()


@pytest.fixture(scope="module")
def ring(tmp_path_factory, scene):
    """Ring capture reconstructed once (real COLMAP) and aligned to the ground truth."""
    root = tmp_path_factory.mktemp("ring")
    images, gt = render_capture(root, ring_cameras(), scene)
    cfg = SfmConfig(camera_model="SIMPLE_RADIAL")
    res = run_sfm(images, SfmOutputs(root / "sfm"), cfg, gt_cameras=gt, keep_work=True)
    return {"root": root, "images": images, "gt": gt, "res": res, "out": root / "sfm"}


# ---- the real reconstruction ----------------------------------------------------------------

def test_ring_registers_all_and_is_accurate(ring):
    r = ring["res"].report
    assert r["registered"] == r["images"] == 20
    assert r["undistorted"] is True and r["camera_models"] == ["SIMPLE_RADIAL"]
    e = r["gt_errors"]
    assert e["rotation_error_deg"]["max"] < 0.5, e
    assert e["center_error_pct_extent"]["max"] < 1.0, e
    assert e["focal_error_pct"]["max"] < 2.0, e


def test_ring_outputs_follow_the_contract(ring):
    out = ring["out"]
    cams = load_cameras(out / "cameras.json")
    names = sorted(p.name for p in ring["images"].iterdir())
    assert [c.name for c in cams] == names
    for c in cams:  # undistorted images lie next to the cameras that describe them
        from PIL import Image

        with Image.open(out / "images" / c.name) as im:
            assert im.size == (c.width, c.height)
        assert c.K[0, 1] == 0 and abs(c.K[0, 0] - c.K[1, 1]) < 1e-9
    pts = np.load(out / "points.npz")
    assert pts["xyz"].dtype == np.float32 and pts["xyz"].shape[1] == 3 and len(pts["xyz"]) > 300
    assert pts["rgb"].shape == pts["xyz"].shape and 0 <= pts["rgb"].min() and pts["rgb"].max() <= 1
    # points lie on the scene: ground (z ~ 0) or boxes, inside the 5 m square (GT frame)
    inside = (np.abs(pts["xyz"][:, :2]) < 2.6).all(1) & (pts["xyz"][:, 2] > -0.1) & (pts["xyz"][:, 2] < 1.4)
    assert inside.mean() > 0.95
    rec = pycolmap.Reconstruction(out / "sparse" / "0")
    assert rec.num_reg_images() == 20
    assert {rec.cameras[i].model.name for i in rec.cameras} <= {"PINHOLE", "SIMPLE_PINHOLE"}
    # the written model and cameras.json agree: reproject the model's points with our cameras
    by_name = {c.name: c for c in cams}
    errs = []
    for image_id in rec.reg_image_ids():
        im = rec.images[image_id]
        for p2 in im.points2D:
            if p2.has_point3D():
                uv, z = by_name[im.name].project(rec.points3D[p2.point3D_id].xyz[None])
                assert z[0] > 0
                errs.append(np.linalg.norm(uv[0] - p2.xy))
    assert np.mean(errs) < 1.0
    # tracks.npz: each image's observations and their depths in the cameras' frame
    tracks = load_tracks(out / "tracks.npz")
    assert sorted(tracks) == names
    for c in cams:
        rows = tracks[c.name]
        assert len(rows) > 20
        assert (rows[:, 0] >= 0).all() and (rows[:, 0] <= c.width).all()
        assert (rows[:, 1] >= 0).all() and (rows[:, 1] <= c.height).all()
    im = rec.images[next(iter(rec.reg_image_ids()))]
    cam = by_name[im.name]
    seen = [p2 for p2 in im.points2D if p2.has_point3D()]
    xy = np.array([p2.xy for p2 in seen])
    uv, z = cam.project(np.array([rec.points3D[p2.point3D_id].xyz for p2 in seen]))
    inside = (xy[:, 0] >= 0) & (xy[:, 0] <= cam.width) & (xy[:, 1] >= 0) & (xy[:, 1] <= cam.height)
    assert np.allclose(tracks[im.name][:, :2], xy[inside], atol=1e-3)
    assert np.allclose(tracks[im.name][:, 2], z[inside], rtol=1e-5)
    rep = ring["res"].report
    for key in ("registered", "images", "mapping", "timings_s", "frame", "gt_errors", "features"):
        assert key in rep
    assert rep["mapping"]["retries"] == 0 and rep["mapping"]["models_found"][0] == 20


def test_upright_frame_without_ground_truth(ring, tmp_path):
    """From the existing model (no GT): up must be +z and the ground z = 0, up to scale."""
    res = run_sfm(ring["images"], SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="SIMPLE_RADIAL"),
                  model_dir=ring["out"] / "work" / "selected")
    assert res.report["frame"]["mode"] == "upright"
    gt = {c.name: c for c in load_cameras(ring["gt"])}
    z = np.array([0.0, 0.0, 1.0])
    for c in res.cameras:  # world up seen from each camera agrees with the ground truth
        a, b = c.R @ z, gt[c.name].R @ z
        assert math.degrees(math.acos(np.clip(a @ b, -1, 1))) < 0.5
    h_est = np.array([c.center[2] for c in res.cameras])
    h_gt = np.array([gt[c.name].center[2] for c in res.cameras])
    s = (h_est @ h_gt) / (h_gt @ h_gt)  # heights above the ground, up to COLMAP's scale
    assert np.abs(h_est - s * h_gt).max() < 0.03 * s * h_gt.mean()
    assert abs(h_est.mean() - 1.6) < 1e-6  # camera_height: scaled to eye height
    centroid = np.mean([c.center for c in res.cameras], axis=0)
    assert np.abs(centroid[:2]).max() < 1e-6 * s


def test_cli_from_existing_model(ring, tmp_path, capsys):
    import json

    from anigs.cli import main

    out = tmp_path / "sfm"
    rc = main(["sfm", "--images", str(ring["images"]), "--out", str(out), "--gt-cameras", str(ring["gt"]),
               "--model", str(ring["out"] / "work" / "selected"),
               "--params", json.dumps({"camera_model": "SIMPLE_RADIAL", "min_registered_fraction": 0.9})])
    assert rc == 0
    assert "registered 20/20 images" in capsys.readouterr().out
    report = json.loads((out / "report.json").read_text())
    assert report["mapping"]["source"].endswith("selected") and report["gt_errors"]["rotation_error_deg"]["max"] < 0.5
    assert sorted(p.name for p in out.iterdir()) == ["cameras.json", "images", "points.npz", "report.json", "sparse", "tracks.npz"]
    assert main(["sfm", "--images", str(ring["images"]), "--out", str(out), "--params", '{"bogus": 1}']) == 1


def test_existing_project_sparse_folder(ring, tmp_path):
    """--model accepts a COLMAP project's sparse/ folder (with 0/ inside), e.g. our own output."""
    res = run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "again"), SfmConfig(camera_model="PINHOLE"),
                  gt_cameras=ring["gt"], model_dir=ring["out"] / "sparse")
    assert res.report["registered"] == 20 and res.report["undistorted"] is False
    assert res.report["gt_errors"]["rotation_error_deg"]["max"] < 0.5
    (tmp_path / "nothing").mkdir()
    with pytest.raises(FileNotFoundError, match="no COLMAP model"):
        run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "x"), model_dir=tmp_path / "nothing")


# ---- fine-scale refinement (anigs.sfm.bundle) on the ring's database and raw model ---------------

def test_ring_refinement_report(ring):
    r = ring["res"].report
    ref = r["refine"]
    assert ref["applied"] is True and "refine" in r["timings_s"]
    assert 0 < ref["observations_kept"] < ref["observations_total"]
    assert 0 < ref["points_kept"] < ref["points_total"] == r["num_points"]  # the output keeps every point
    assert ref["min_observations_per_image"] >= 2 and ref["cauchy_loss_scale_px"] > 0
    assert ref["mean_reprojection_error_after_px"] < 1.0


def test_keypoint_scales_and_pruning(ring):
    from anigs.sfm.bundle import keypoint_scales, prune_coarse_observations

    db = ring["out"] / "work" / "database.db"
    rec = pycolmap.Reconstruction(ring["out"] / "work" / "selected")
    scales = keypoint_scales(db, rec)
    ids = sorted(rec.reg_image_ids())
    for i in ids:
        assert len(scales[i]) == rec.images[i].num_points2D() and (scales[i] > 0).all()
    assert min(s.min() for s in scales.values()) < 1.3 < max(s.max() for s in scales.values())
    half = keypoint_scales(db, rec, max_image_size=W // 2)  # SIFT ran on half-size images
    assert np.allclose(half[ids[0]], scales[ids[0]] / 2)

    same = pycolmap.Reconstruction(rec)
    rep = prune_coarse_observations(same, scales, 1e9, 0)
    assert rep["observations_kept"] == rep["observations_total"] and same.num_points3D() == rec.num_points3D()

    fine = pycolmap.Reconstruction(rec)
    rep = prune_coarse_observations(fine, scales, 1.3, 10)
    assert 0 < rep["observations_kept"] < rep["observations_total"]
    assert rep["points_kept"] == fine.num_points3D() < rec.num_points3D()
    for i in ids:  # each image keeps scales up to 1.3 px, or up to its 10th finest if that is coarser
        before = np.sort(scales[i][rec.images[i].get_observation_point2D_idxs()])
        limit = max(1.3, before[min(10, len(before)) - 1])
        assert (scales[i][fine.images[i].get_observation_point2D_idxs()] <= limit).all()
    assert all(p.track.length() >= 2 for p in fine.points3D.values())


def test_refinement_undoes_a_camera_perturbation(ring):
    from anigs.sfm.bundle import refine_fine_scale

    rec = pycolmap.Reconstruction(ring["out"] / "work" / "selected")
    ids = sorted(rec.reg_image_ids())
    ref = {i: rec.images[i].cam_from_world().rotation.matrix() for i in ids}
    a, b = ids[5], ids[6]
    frame = rec.frames[rec.images[a].frame_id]
    pose = frame.rig_from_world
    c, s = math.cos(math.radians(0.5)), math.sin(math.radians(0.5))
    tilt = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])  # 0.5 degrees about the camera's x axis
    frame.rig_from_world = pycolmap.Rigid3d(pycolmap.Rotation3d(tilt @ pose.rotation.matrix()),
                                            np.asarray(pose.translation).reshape(3, 1))
    relative = lambda r: rotation_angle_deg(r[a] @ r[b].T, ref[a] @ ref[b].T)  # noqa: E731
    moved = {i: rec.images[i].cam_from_world().rotation.matrix() for i in ids}
    assert relative(moved) > 0.45
    n_points = rec.num_points3D()
    report = refine_fine_scale(rec, ring["out"] / "work" / "database.db", max_keypoint_scale=1.3,
                               min_observations=60, loss_scale=0.5)
    after = {i: rec.images[i].cam_from_world().rotation.matrix() for i in ids}
    assert relative(after) < 0.1, relative(after)
    assert rec.num_points3D() == n_points and report["points_total"] == n_points
    assert report["mean_reprojection_error_after_px"] < report["mean_reprojection_error_before_px"]


# ---- failure handling (mapper replaced; the images and model are the ring's) -------------

def _patch_colmap(monkeypatch, models_for_angle):
    """Skip extraction/matching; the mapper returns models_for_angle(angle) or raises it."""
    calls = []

    def fake_extract(database, image_dir, names, cfg, mode=None):
        return {"extract_s": 0.0, "match_s": 0.0, "extract_cpu_s": 0.0, "match_cpu_s": 0.0}

    def fake_mapper(database, image_dir, out_dir, cfg, names, mapper, angle):
        calls.append(angle)
        result = models_for_angle(angle)
        if isinstance(result, Exception):
            raise result
        return result

    monkeypatch.setattr(steps, "extract_and_match", fake_extract)
    monkeypatch.setattr(steps, "run_mapper", fake_mapper)
    return calls


def _partial(rec, keep: int):
    part = pycolmap.Reconstruction(rec)
    for fid in sorted(part.reg_frame_ids())[keep:]:
        part.deregister_frame(fid)
    return part


@pytest.fixture(scope="module")
def ring_model(ring):
    return pycolmap.Reconstruction(ring["out"] / "sparse" / "0")


def test_several_models_keep_the_largest(ring, ring_model, tmp_path, monkeypatch, caplog):
    small = _partial(ring_model, 5)
    calls = _patch_colmap(monkeypatch, lambda angle: {0: small, 1: pycolmap.Reconstruction(ring_model)})
    with caplog.at_level(logging.WARNING, logger="anigs.sfm.colmap"):
        res = run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="PINHOLE"))
    assert calls == [16.0]
    assert res.report["mapping"]["models_found"] == [20, 5]
    assert res.report["mapping"]["other_models"] == [5]
    assert len(res.cameras) == 20
    assert "keeping the largest" in caplog.text
    assert res.report["refine"] == {"applied": False, "reason": "no feature database (model not mapped here)"}


def test_too_few_registered_goes_on_partial_or_fails_after_retry(ring, ring_model, tmp_path, monkeypatch):
    part = _partial(ring_model, 14)  # 14/20 = 0.7: below 0.8, at least half
    calls = _patch_colmap(monkeypatch, lambda angle: {0: pycolmap.Reconstruction(part)})
    res = run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="PINHOLE"))
    assert calls == [16.0, 4.0] + [16.0] * 4  # then the best attempt again with 4 other mapper seeds (restart)
    assert [a["seed"] for a in res.report["mapping"]["attempts"]] == [0, 0, 1, 2, 3, 4]
    assert res.report["status"] == "partial" and res.report["registered"] == 14
    assert len(res.report["unregistered_images"]) == 6 and len(res.cameras) == 14
    # below partial_min_fraction it is an error naming registered/total and both attempts
    calls = _patch_colmap(monkeypatch, lambda angle: {0: pycolmap.Reconstruction(_partial(ring_model, 9))})
    with pytest.raises(SfmError, match=r"registered 9/20 images") as err:
        run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm2"), SfmConfig(camera_model="PINHOLE", mapper_restarts=0))
    assert calls == [16.0, 4.0]
    assert "init_min_tri_angle=4.0" in str(err.value) and "Settings to try" in str(err.value)
    assert not (tmp_path / "sfm2" / "cameras.json").exists()
    # a lower threshold accepts the same model as complete
    res = run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm3"),
                  SfmConfig(camera_model="PINHOLE", min_registered_fraction=0.4))
    assert res.report["registered"] == 9 and res.report["status"] == "complete"
    assert len(res.report["unregistered_images"]) == 11


def test_mapping_failure_retries_with_lower_angle(ring, ring_model, tmp_path, monkeypatch, caplog):
    def models(angle):
        return RuntimeError("no good initial image pair found") if angle > 10 else {0: pycolmap.Reconstruction(ring_model)}

    calls = _patch_colmap(monkeypatch, models)
    with caplog.at_level(logging.WARNING, logger="anigs.sfm.colmap"):
        res = run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="PINHOLE"))
    assert calls == [16.0, 4.0]
    attempts = res.report["mapping"]["attempts"]
    assert res.report["mapping"]["retries"] == 1 and "no good initial image pair" in attempts[0]["result"]
    assert [a["step"] for a in attempts] == ["first", "lower_angle"]
    assert attempts[1]["registered"] == 20
    assert "retrying mapping with init_min_tri_angle=4" in caplog.text
    # a failure with the retry disabled is an error naming 0/20
    _patch_colmap(monkeypatch, lambda a: RuntimeError("boom"))
    with pytest.raises(SfmError, match=r"registered 0/20"):
        run_sfm(ring["out"] / "images", SfmOutputs(tmp_path / "sfm3"),
                SfmConfig(camera_model="PINHOLE", retry_init_min_tri_angle=None))


# ---- checks before COLMAP runs ---------------------------------------------------------------

def _forbid_colmap(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("COLMAP must not run")

    monkeypatch.setattr(steps, "extract_and_match", boom)


def test_corrupt_images_listed_or_skipped(ring, tmp_path, monkeypatch, caplog):
    folder = tmp_path / "imgs"
    folder.mkdir()
    for p in sorted(ring["images"].iterdir())[:4]:
        (folder / p.name).write_bytes(p.read_bytes())
    good = (folder / "ring_000.png").read_bytes()
    (folder / "truncated.png").write_bytes(good[: len(good) // 3])
    (folder / "noise.jpg").write_bytes(np.random.default_rng(0).bytes(3000))
    _forbid_colmap(monkeypatch)
    with pytest.raises(ValueError) as err:
        run_sfm(folder, SfmOutputs(tmp_path / "sfm"))
    assert "2 unreadable" in str(err.value)
    assert "truncated.png" in str(err.value) and "noise.jpg" in str(err.value)

    seen = {}

    def record(database, image_dir, names, cfg, mode=None):
        seen["names"] = names
        raise RuntimeError("stop here")

    monkeypatch.setattr(steps, "extract_and_match", record)
    with caplog.at_level(logging.WARNING), pytest.raises(RuntimeError, match="stop here"):
        run_sfm(folder, SfmOutputs(tmp_path / "sfm"), SfmConfig(skip_unreadable=True))
    assert seen["names"] == [f"ring_{i:03d}.png" for i in range(4)]
    assert "truncated.png" in caplog.text and "noise.jpg" in caplog.text
    assert not list((tmp_path / "sfm").glob(".sfm_work.*"))  # work folder cleaned up


def test_fewer_than_three_images(ring, tmp_path, monkeypatch):
    folder = tmp_path / "two"
    folder.mkdir()
    for p in sorted(ring["images"].iterdir())[:2]:
        (folder / p.name).write_bytes(p.read_bytes())
    _forbid_colmap(monkeypatch)
    with pytest.raises(ValueError, match="at least 3"):
        run_sfm(folder, SfmOutputs(tmp_path / "sfm"))
    assert not (tmp_path / "sfm").exists()  # failed before creating anything
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not an image")
    with pytest.raises(FileNotFoundError, match="no JPEG/PNG"):
        run_sfm(tmp_path / "empty", SfmOutputs(tmp_path / "out"))
    with pytest.raises(FileNotFoundError, match="not found"):
        run_sfm(tmp_path / "missing", SfmOutputs(tmp_path / "out"))


def test_mixed_sizes_and_exif_rotation_checked_first(ring, tmp_path, monkeypatch, caplog):
    from PIL import Image

    folder = tmp_path / "imgs"
    folder.mkdir()
    srcs = sorted(ring["images"].iterdir())[:4]
    for p in srcs[:3]:
        (folder / p.name).write_bytes(p.read_bytes())
    with Image.open(srcs[3]) as im:
        exif = Image.Exif()
        exif[0x0112] = 6
        im.save(folder / "turned.jpg", exif=exif, quality=95)
        im.resize((160, 120)).save(folder / "small.png")
    _forbid_colmap(monkeypatch)
    with caplog.at_level(logging.WARNING), pytest.raises(ValueError, match="2 sizes.*single_camera"):
        run_sfm(folder, SfmOutputs(tmp_path / "sfm"))
    assert "EXIF rotation" in caplog.text and "turned.jpg" in caplog.text


def test_spatial_matcher_needs_location_priors(ring, tmp_path):
    folder = tmp_path / "imgs"
    folder.mkdir()
    for p in sorted(ring["images"].iterdir())[:3]:
        (folder / p.name).write_bytes(p.read_bytes())
    with pytest.raises(ValueError, match="spatial.*EXIF GPS"):
        run_sfm(folder, SfmOutputs(tmp_path / "sfm"), SfmConfig(matcher="spatial"))


def test_config_rejects_unknown_and_bad_values():
    with pytest.raises(KeyError, match="init_tri_angle"):
        SfmConfig.from_dict({"init_tri_angle": 4})
    with pytest.raises(ValueError, match="matcher"):
        SfmConfig.from_dict({"matcher": "vocab"})
    with pytest.raises(ValueError, match="camera_model"):
        SfmConfig.from_dict({"camera_model": "FISHY"})
    with pytest.raises(ValueError, match="min_registered_fraction"):
        SfmConfig.from_dict({"min_registered_fraction": 0})
    with pytest.raises(ValueError, match="takes 4"):
        SfmConfig.from_dict({"camera_model": "SIMPLE_RADIAL", "camera_params": [300, 160, 120]})
    with pytest.raises(ValueError, match="num_threads"):
        SfmConfig.from_dict({"num_threads": 0})
    for key, bad in (("mapper_num_threads", -2), ("matching_num_threads", 0), ("init_min_tri_angle", "wide"), ("init_min_tri_angle", 95),
                     ("exhaustive_max_images", 1), ("exhaustive_max_comparisons", 0), ("sequential_similar", -1),
                     ("ba_global_growth", 1.0), ("ba_global_max_refinements", 0), ("ba_local_max_refinements", 0)):
        with pytest.raises(ValueError, match=key):
            SfmConfig.from_dict({key: bad})
    assert SfmConfig.from_dict({}).matcher == "auto" and SfmConfig.from_dict({}).init_min_tri_angle == "auto"
    for key, bad in (("refine_max_keypoint_scale", 0), ("refine_min_observations", -1), ("refine_loss_scale", -0.5),
                     ("sift_peak_threshold", 0), ("seed", -1), ("seed", 1.5), ("seed", 2**31)):
        with pytest.raises(ValueError, match=key):
            SfmConfig.from_dict({key: bad})
    assert SfmConfig.from_dict({"matcher": "sequential"}).matcher == "sequential"


def _busy_cpu0():
    """A process spinning on CPU 0 (stopped by the caller), and CPU 0 for a child to share it."""
    spin = subprocess.Popen([sys.executable, "-c", "while True: pass"], preexec_fn=lambda: os.sched_setaffinity(0, {0}))
    return spin, (lambda: os.sched_setaffinity(0, {0}))


def test_same_seed_same_output_for_any_extraction_thread_count(ring, tmp_path):
    """matching_num_threads=1 and mapper_num_threads=1 (the defaults) make the stage bit-deterministic for a
    seed, whatever num_threads extraction and undistortion use, and however their threads are scheduled:
    1 thread, 2 threads, and 3 threads sharing one CPU with a busy process (the CLI, as the
    workflow runs it) give the same bytes and the same fingerprint after every step."""
    folder = tmp_path / "imgs"
    folder.mkdir()
    for p in sorted(ring["images"].iterdir())[:7]:  # 7 neighbouring views: a quick reconstruction
        (folder / p.name).write_bytes(p.read_bytes())
    a = run_sfm(folder, SfmOutputs(tmp_path / "a"), SfmConfig(camera_model="SIMPLE_RADIAL", num_threads=1), keep_work=True)
    b = run_sfm(folder, SfmOutputs(tmp_path / "b"), SfmConfig(camera_model="SIMPLE_RADIAL", num_threads=2), keep_work=True)
    spin, on_cpu0 = _busy_cpu0()
    try:
        done = subprocess.run([sys.executable, "-m", "anigs.cli", "--threads", "3", "sfm", "--images", str(folder),
                               "--out", str(tmp_path / "c"), "--params", '{"camera_model": "SIMPLE_RADIAL"}'],
                              capture_output=True, text=True, preexec_fn=on_cpu0)
    finally:
        spin.kill()
        spin.wait()
    assert done.returncode == 0, done.stderr[-3000:]
    c = SfmOutputs(tmp_path / "c")
    assert a.report["registered"] == 7
    assert (a.report["auto"]["num_threads"], b.report["auto"]["num_threads"], c.report()["auto"]["num_threads"]) == (1, 2, 3)
    assert a.report["auto"]["mapper_num_threads"] == b.report["auto"]["mapper_num_threads"] == 1
    assert a.report["auto"]["matching_num_threads"] == c.report()["auto"]["matching_num_threads"] == 1
    assert set(a.report["fingerprints"]) == {"features", "matches", "mapped", "model"}
    assert a.report["fingerprints"] == b.report["fingerprints"] == c.report()["fingerprints"]
    assert np.array_equal(a.xyz, b.xyz) and np.array_equal(a.rgb, b.rgb)
    assert all(np.array_equal(x.viewmat, y.viewmat) and np.array_equal(x.K, y.K) for x, y in zip(a.cameras, b.cameras))
    assert (tmp_path / "a" / "cameras.json").read_bytes() == c.path("cameras").read_bytes()
    assert (tmp_path / "a" / "points.npz").read_bytes() == c.path("points").read_bytes()
    for name in sorted(p.name for p in (tmp_path / "a" / "images").iterdir()):  # undistorted with 1, 2 and 3 threads
        assert (tmp_path / "a" / "images" / name).read_bytes() == (tmp_path / "b" / "images" / name).read_bytes()
        assert (tmp_path / "a" / "images" / name).read_bytes() == c.path("images").joinpath(name).read_bytes()
    da, db = (pycolmap.Database.open(str(tmp_path / x / "work" / "database.db")) for x in "ab")
    try:
        for im in da.read_all_images():
            assert np.array_equal(da.read_keypoints(im.image_id), db.read_keypoints(im.image_id))
            assert np.array_equal(da.read_descriptors(im.image_id).data, db.read_descriptors(im.image_id).data)
        (pa, ga), (pb, gb) = da.read_two_view_geometries(), db.read_two_view_geometries()
        assert sorted(pa) == sorted(pb)
        by_a, by_b = dict(zip(pa, ga)), dict(zip(pb, gb))
        for pid in pa:
            assert np.array_equal(by_a[pid].inlier_matches, by_b[pid].inlier_matches)
            assert np.array_equal(by_a[pid].F, by_b[pid].F)
    finally:
        da.close()
        db.close()


def test_fingerprints_name_the_step_that_changed(ring, tmp_path):
    """The report's fingerprints are digests of the kept database and model: they match a recomputation,
    and change when one inlier match, one descriptor byte or one pose changes."""
    fp = ring["res"].report["fingerprints"]
    database = ring["out"] / "work" / "database.db"
    assert {k: fp[k] for k in ("features", "matches")} == database_fingerprints(database)
    changed = tmp_path / "changed.db"
    shutil.copy(database, changed)
    db = pycolmap.Database.open(str(changed))
    try:
        pair_ids, geoms = db.read_two_view_geometries()
        k = int(np.argmax([len(g.inlier_matches) for g in geoms]))
        g = geoms[k]
        g.inlier_matches = np.asarray(g.inlier_matches)[1:]
        i, j = pycolmap.pair_id_to_image_pair(pair_ids[k])
        db.update_two_view_geometry(i, j, g)
    finally:
        db.close()
    after = database_fingerprints(changed)
    assert after["features"] == fp["features"] and after["matches"] != fp["matches"]
    rec = pycolmap.Reconstruction(ring["out"] / "sparse" / "0")
    same = pycolmap.Reconstruction(rec)
    assert model_fingerprint(rec) == model_fingerprint(same)
    image_id = sorted(same.reg_image_ids())[0]
    frame = same.frames[same.images[image_id].frame_id]
    pose = frame.rig_from_world
    pose.translation = np.asarray(pose.translation) + np.array([1e-9, 0, 0])
    frame.rig_from_world = pose
    assert model_fingerprint(rec) != model_fingerprint(same)


# ---- choices from the capture (anigs.sfm.plan) ------------------------------------------------

def _copy_as(paths, folder: Path, names) -> list[Path]:
    folder.mkdir()
    for p, n in zip(paths, names):
        (folder / n).write_bytes(p.read_bytes())
    return sorted(folder.iterdir())


def test_auto_matcher_choice(ring, tmp_path, caplog):
    orbit = sorted(ring["images"].iterdir())  # 20 views around the scene, in order
    assert plan.ordering(orbit)["ordered"]
    pick = lambda paths, kp, max_images=300: plan.choose_matcher("auto", paths, max_images, 2e9, kp)
    # ordered: sequential only when exhaustive matching would be expensive (190 pairs x keypoints^2)
    assert pick(orbit, 5000)[0] == "sequential"
    matcher, why = pick(orbit, 1000)
    assert matcher == "exhaustive" and "cheap" in why["reason"] and why["exhaustive_comparisons"] == 190e6
    # the same photos shuffled are not ordered: exhaustive, unless there are too many of them
    perm = np.random.default_rng(0).permutation(len(orbit))
    shuffled = _copy_as([orbit[i] for i in perm], tmp_path / "shuffled", [p.name for p in orbit])
    assert not plan.ordering(shuffled)["ordered"]
    assert pick(shuffled, 5000)[0] == "exhaustive"
    with caplog.at_level(logging.WARNING, logger="anigs.sfm.plan"):
        assert pick(shuffled, 100, max_images=10)[0] == "sequential"
    assert "do not look ordered" in caplog.text
    assert pick(orbit[:15], 5000)[0] == "exhaustive"  # few photos: always exhaustive
    assert plan.choose_matcher("sequential", shuffled, 300, 2e9, 10)[0] == "sequential"  # explicit: kept


def test_similar_pairs_close_the_orbit(ring):
    orbit = sorted(ring["images"].iterdir())
    pairs = plan.similar_pairs(orbit, 3, overlap=10)
    assert (0, 19) in pairs  # first and last view: neighbours on the circle, 19 apart in the order
    assert not set(pairs) & plan.sequential_offsets(20, 10)
    assert plan.sequential_offsets(34, 10) == {(i, i + d) for d in (1, 2, 4, 8, 16, 32) for i in range(34 - d)}
    assert plan.similar_pairs(orbit, 0, overlap=10) == []


def test_thread_counts():
    assert plan.resolve_threads(3, cli_threads=8) == 3
    assert plan.resolve_threads(-1, cli_threads=2) == 2
    assert plan.resolve_threads(-1) == plan.available_cpus() >= 1
    cfg, info = sfm_mod.resolve_config(SfmConfig(num_threads=-1, matching_num_threads=-1, mapper_num_threads=-1),
                                       cli_threads=5)
    assert (cfg.num_threads, cfg.matching_num_threads, cfg.mapper_num_threads) == (5, 5, 5) \
        == (info["num_threads"], info["matching_num_threads"], info["mapper_num_threads"])
    cfg, _ = sfm_mod.resolve_config(SfmConfig(), cli_threads=5)
    assert (cfg.num_threads, cfg.matching_num_threads, cfg.mapper_num_threads) == (5, 1, 1)


def test_initial_pair_angle_from_the_matches(ring, tmp_path):
    angles, inliers = plan.pair_triangulation_angles(ring["out"] / "work" / "database.db")
    assert len(angles) == len(inliers) > 10 and np.all(angles >= 0)
    angle, info = plan.initial_pair_angle(ring["out"] / "work" / "database.db")
    assert angle == 16.0 and info["largest_pair_angle_deg"] >= 16  # views 18 degrees apart on the orbit
    assert ring["res"].report["mapping"]["init_min_tri_angle_auto"]["angle"] == 16.0
    assert plan.initial_pair_angle(tmp_path / "missing.db") == (16.0, {"angle": 16.0, "reason": "no feature database"})


def test_auto_sequential_matching_of_an_orbit(ring, tmp_path):
    """Forced to sequential (tiny comparison budget), the orbit still registers every view: the
    similar-thumbnail pairs close the loop that COLMAP's sequential pairs leave open."""
    cfg = SfmConfig(camera_model="SIMPLE_PINHOLE", exhaustive_max_comparisons=1.0, refine=False)
    r = run_sfm(ring["images"], SfmOutputs(tmp_path / "sfm"), cfg, gt_cameras=ring["gt"]).report
    assert r["auto"]["matcher"] == "sequential" and "ordered" in r["auto"]["matcher_choice"]["reason"]
    assert r["features"]["similar_pairs"] > 0
    assert r["registered"] == r["images"] == 20
    assert r["gt_errors"]["rotation_error_deg"]["max"] < 1.0, r["gt_errors"]


def test_held_distortion_is_estimated_without_refinement(ring, tmp_path):
    """SIMPLE_RADIAL: the mapper holds k at zero; with refine off one last bundle adjustment
    estimates it (with refine on, the refinement does: the ring fixture)."""
    assert SfmConfig(camera_model="SIMPLE_RADIAL").mapper_holds_distortion()
    assert not SfmConfig(camera_model="OPENCV").mapper_holds_distortion()
    assert not SfmConfig(camera_model="SIMPLE_RADIAL", mapper_refine_distortion=True).mapper_holds_distortion()
    folder = tmp_path / "imgs"
    folder.mkdir()
    for p in sorted(ring["images"].iterdir())[:7]:
        (folder / p.name).write_bytes(p.read_bytes())
    r = run_sfm(folder, SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="SIMPLE_RADIAL", refine=False), keep_work=True).report
    adj = r["refine"]["intrinsics_adjustment"]
    assert adj["mean_reprojection_error_after_px"] <= adj["mean_reprojection_error_before_px"] + 1e-9
    raw = pycolmap.Reconstruction(tmp_path / "sfm" / "work" / "selected")
    assert all(c.params[3] != 0 for c in raw.cameras.values())  # k estimated, not left at zero
    assert r["undistorted"] is True
    ring_raw = pycolmap.Reconstruction(ring["out"] / "work" / "selected")
    assert all(c.params[3] != 0 for c in ring_raw.cameras.values())


# ---- a real forward-facing capture -------------------------------------------------------------

def test_forward_facing_capture(tmp_path, scene):
    images, gt = render_capture(tmp_path, forward_cameras(), scene)
    res = run_sfm(images, SfmOutputs(tmp_path / "sfm"), SfmConfig(camera_model="SIMPLE_PINHOLE", matcher="sequential"),
                  gt_cameras=gt)
    r = res.report
    assert r["registered"] == r["images"] == 16
    assert r["undistorted"] is False
    # forward-facing: no pair reaches 16 degrees; the mapper starts lower instead of failing at 16
    assert r["mapping"]["init_min_tri_angle_auto"]["angle"] < 16 and r["mapping"]["retries"] == 0
    e = r["gt_errors"]
    # small baseline: the centres pin the alignment rotation down loosely, the orientations do not
    assert e["rotation_error_deg_after_best_rotation"]["max"] < 0.5, e
    assert e["center_error_pct_extent"]["max"] < 3.0, e


# ---- similarity algebra -------------------------------------------------------------------------

def _random_similarity(rng) -> Similarity:
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return Similarity(float(rng.uniform(0.3, 3)), R, rng.standard_normal(3))


def test_umeyama_recovers_a_similarity():
    rng = np.random.default_rng(3)
    sim = _random_similarity(rng)
    src = rng.standard_normal((30, 3))
    fit = umeyama(src, sim.apply(src))
    assert abs(fit.scale - sim.scale) < 1e-9 and np.allclose(fit.R, sim.R) and np.allclose(fit.t, sim.t)
    noisy = umeyama(src, sim.apply(src) + 1e-3 * rng.standard_normal(src.shape))
    assert rotation_angle_deg(noisy.R, sim.R) < 0.5
    with pytest.raises(ValueError, match="collinear"):
        umeyama(np.outer(np.arange(5.0), [1, 2, 3]), np.outer(np.arange(5.0), [3, 2, 1]))
    with pytest.raises(ValueError, match="at least 3"):
        umeyama(src[:2], src[:2])


def test_similarity_keeps_projections_and_pose_errors():
    rng = np.random.default_rng(4)
    sim = _random_similarity(rng)
    cams = ring_cameras(6)
    pts = rng.uniform(-1, 1, (50, 3))
    for c in cams:
        moved = sim.apply_camera(c)
        assert np.allclose(moved.R @ moved.R.T, np.eye(3))
        uv0, z0 = c.project(pts)
        uv1, z1 = moved.project(sim.apply(pts))
        assert np.allclose(uv0, uv1) and np.allclose(z1, sim.scale * z0)
    inv_moved = [sim.apply_camera(c) for c in cams]
    back = umeyama(np.stack([c.center for c in inv_moved]), np.stack([c.center for c in cams]))
    e = pose_errors([back.apply_camera(c) for c in inv_moved], cams)
    assert e["rotation_error_deg"]["max"] < 1e-6 and e["center_error_pct_extent"]["max"] < 1e-6
    both = sim.compose(back)
    assert np.allclose(both.apply(pts), sim.apply(back.apply(pts)))


def test_rotation_between():
    rng = np.random.default_rng(5)
    for _ in range(20):
        a, b = rng.standard_normal(3), rng.standard_normal(3)
        R = rotation_between(a, b)
        assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1)
        assert np.allclose(R @ (a / np.linalg.norm(a)), b / np.linalg.norm(b))
    R = rotation_between(np.array([0, 0, 1.0]), np.array([0, 0, -1.0]))
    assert np.allclose(R @ [0, 0, 1], [0, 0, -1]) and np.isclose(np.linalg.det(R), 1)


def test_estimate_up_ignores_a_common_pitch():
    rng = np.random.default_rng(6)
    K = intrinsics_from_fov(60, W, H)
    sim = _random_similarity(rng)  # an arbitrary reconstruction frame
    cams = []
    for yaw in np.radians(rng.uniform(-40, 40, 12)):  # half-circle of views, all pitched 20 deg down
        eye = rng.standard_normal(3) * [1, 1, 0.1] + [0, 0, 1.6]
        fwd = [math.cos(yaw) * math.cos(-0.35), math.sin(yaw) * math.cos(-0.35), math.sin(-0.35)]
        cams.append(sim.apply_camera(Camera(K, look_at(eye, eye + np.array(fwd)), W, H)))
    up = estimate_up(cams).up
    assert math.degrees(math.acos(np.clip(up @ sim.R[:, 2], -1, 1))) < 0.1
    # all facing one way: undetermined within the plane orthogonal to x, the mean -y is used
    same = [cams[0]] * 5
    up1 = estimate_up(same).up
    assert abs(up1 @ same[0].R[0]) < 1e-6 and up1 @ -same[0].R[1] > 0.999


@pytest.mark.parametrize("deg", [0.0, 1e-9, 1e-6, 0.01, 45.0, 90.0, 179.999, 180.0])
def test_rotation_angle_is_accurate_at_every_angle(deg):
    """The pose-error metric: atan2 of the skew part against the trace, not acos of the trace alone
    (which reads ~1e-6 degrees for identical rotations)."""
    from scipy.spatial.transform import Rotation

    from anigs.sfm.align import rotation_angle_deg

    rng = np.random.default_rng(int(deg * 1000) % 2**32)
    for _ in range(5):
        Rb = Rotation.random(random_state=rng).as_matrix()
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        Rd = Rotation.from_rotvec(np.radians(deg) * axis).as_matrix()
        got = rotation_angle_deg(Rd @ Rb, Rb)
        assert abs(got - deg) <= 1e-9 * max(1.0, deg) + 1e-12, (deg, got)


def test_portrait_and_landscape_photos_need_no_config(ring, tmp_path):
    """Phone photos of mixed orientation: the sizes differ only by a 90-degree turn, so each
    orientation gets its own camera (COLMAP AUTO) instead of an error asking to edit config."""
    import cv2

    from anigs.sfm.colmap import camera_mode

    assert camera_mode(SfmConfig(), [(W, H)]) == "SINGLE"
    assert camera_mode(SfmConfig(), sorted([(W, H), (H, W)])) == "AUTO"
    assert camera_mode(SfmConfig(single_camera=False), [(W, H), (7, 5)]) == "PER_IMAGE"
    with pytest.raises(ValueError, match="not one size turned by 90 degrees"):
        camera_mode(SfmConfig(), [(W, H), (W // 2, H // 2)])
    folder = tmp_path / "imgs"
    folder.mkdir()
    srcs = sorted(ring["images"].iterdir())
    for i, p in enumerate(srcs):
        img = cv2.imread(str(p))
        cv2.imwrite(str(folder / p.name), np.ascontiguousarray(np.rot90(img)) if i % 3 == 0 else img)
    res = run_sfm(folder, SfmOutputs(tmp_path / "sfm"))
    assert res.report["camera_mode"] == "AUTO"
    assert res.report["registered"] == len(srcs), res.report["registered"]
    cams = load_cameras(tmp_path / "sfm" / "cameras.json")  # undistorted: sizes within a few pixels
    assert sum(c.width < c.height for c in cams) == sum(i % 3 == 0 for i in range(len(srcs)))
    assert all(abs(max(c.width, c.height) - W) <= 8 and abs(min(c.width, c.height) - H) <= 8 for c in cams)
