"""A COLMAP project as a scene source (``source: colmap``): the sfm stage reads the user's model, text or
binary, instead of running SfM (anigs.sfm.colmap._existing_model), and the workflow has no SfM job."""
from __future__ import annotations

import logging
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pycolmap = pytest.importorskip("pycolmap")

from anigs.cameras import Camera, intrinsics_from_fov, load_cameras  # noqa: E402
from anigs.config import load_scene  # noqa: E402
from anigs.sfm.colmap import SfmConfig, SfmError, run_sfm  # noqa: E402
from anigs.sfm.model import reconstruction_cameras  # noqa: E402
from anigs.sfm.tracks import load_tracks  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402
from anigs.static.imported import sfm_frame  # noqa: E402
from _captures import H, W, ring_positions, textured_boxes  # noqa: E402
from _project import colmap_project, write_text_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    root = tmp_path_factory.mktemp("project")
    K = intrinsics_from_fov(60, W, H)
    cams = [Camera(K, v, W, H, f"ring_{k:02d}.jpg".replace(".jpg", ".png")) for k, v in enumerate(ring_positions(10))]
    scene = textured_boxes(0, 1500, 300)
    return {**colmap_project(root, cams, scene), "cams": cams, "root": root}


@pytest.fixture(scope="module")
def imported(project, tmp_path_factory):
    """The sfm stage run on the text and on the binary form of the same project."""
    out = {}
    for form in ("text", "binary"):
        folder = SfmOutputs(tmp_path_factory.mktemp(form) / "sfm")
        res = run_sfm(project["images"], folder, SfmConfig(), model_dir=project[form])
        res.folder = folder
        out[form] = res
    return out


def test_cameras_json_is_pycolmaps_reading_in_the_reported_frame(project, imported):
    """Each camera is pycolmap's reading of the user's model (text and binary) taken through the similarity
    sfm/report.json records (the z-up normalisation every later stage relies on)."""
    for form in ("text", "binary"):
        assert imported[form].report["mapping"]["model_format"] == form
        assert imported[form].report["registered"] == 10 and imported[form].report["unregistered_images"] == []
        rec = pycolmap.Reconstruction(str(project[form]))
        theirs = {c.name: c for c in reconstruction_cameras(rec)}
        sim = sfm_frame(imported[form].folder.path("report"))
        ours = imported[form].cameras
        assert sorted(theirs) == [c.name for c in ours]
        for c in ours:
            want = sim.apply_camera(theirs[c.name])
            assert np.allclose(c.K, want.K, atol=1e-9) and (c.width, c.height) == (want.width, want.height)
            assert np.allclose(c.viewmat, want.viewmat, atol=1e-9)


def test_both_forms_write_identical_files(project, tmp_path):
    dirs = {}
    for form in ("text", "binary"):
        out = SfmOutputs(tmp_path / form / "sfm")
        run_sfm(project["images"], out, SfmConfig(), model_dir=project[form])
        dirs[form] = out
    for key in ("cameras", "points", "tracks"):
        assert dirs["text"].path(key).read_bytes() == dirs["binary"].path(key).read_bytes(), key
    # the user's cameras, in anigs's z-up frame: the tracks hold every observation of the model
    tracks = load_tracks(dirs["text"].path("tracks"))
    rec = pycolmap.Reconstruction(str(project["text"]))
    assert sum(len(v) for v in tracks.values()) == sum(
        sum(p.has_point3D() for p in rec.images[i].points2D) for i in rec.reg_image_ids())
    cams = load_cameras(dirs["text"].path("cameras"))
    ups = np.stack([-c.R[1] for c in cams])  # image up (-y) in the world: near +z for upright photos
    assert ups.mean(0)[2] > 0.8


def test_unregistered_images_are_named_in_the_log(project, tmp_path, caplog):
    images = tmp_path / "images"
    shutil.copytree(project["images"], images)
    shutil.copy(images / "ring_00.png", images / "stray.png")
    with caplog.at_level(logging.WARNING, logger="anigs.sfm.colmap"):
        res = run_sfm(images, SfmOutputs(tmp_path / "sfm"), SfmConfig(), model_dir=project["text"])
    assert res.report["unregistered_images"] == ["stray.png"]
    assert any("does not register 1 of the 11 images" in r.message and "stray.png" in r.message
               for r in caplog.records)


def test_a_downscaled_image_folder_rescales_the_cameras(project, tmp_path):
    import cv2

    half = tmp_path / "images_2"
    half.mkdir()
    for p in sorted(project["images"].glob("*.png")):
        cv2.imwrite(str(half / p.name), cv2.resize(cv2.imread(str(p)), (W // 2, H // 2), interpolation=cv2.INTER_AREA))
    res = run_sfm(half, SfmOutputs(tmp_path / "sfm"), SfmConfig(), model_dir=project["text"])
    full = run_sfm(project["images"], SfmOutputs(tmp_path / "full"), SfmConfig(), model_dir=project["text"])
    a, b = res.cameras[0], full.cameras[0]
    assert (a.width, a.height) == (W // 2, H // 2)
    assert np.allclose(a.K[0, 0] * 2, b.K[0, 0]) and np.allclose(a.viewmat, b.viewmat, atol=1e-9)
    assert res.report["mapping"]["rescaled_to_images"]


def test_another_shape_of_image_is_refused(project, tmp_path):
    import cv2

    odd = tmp_path / "images"
    shutil.copytree(project["images"], odd)
    img = cv2.imread(str(odd / "ring_03.png"))
    cv2.imwrite(str(odd / "ring_03.png"), img[:, : W - 40])
    with pytest.raises(ValueError, match=r"ring_03.png is 280x240 but its camera .* is 320x240"):
        run_sfm(odd, SfmOutputs(tmp_path / "sfm"), SfmConfig(), model_dir=project["text"])


def test_a_distorted_model_is_undistorted_through_pycolmap(project, tmp_path):
    model = tmp_path / "sparse" / "0"
    K = project["cams"][0].K
    write_text_model(model, project["cams"], np.zeros((0, 3)), np.zeros((0, 3)), "SIMPLE_RADIAL",
                     (K[0, 0], K[0, 2], K[1, 2], 0.05))
    res = run_sfm(project["images"], SfmOutputs(tmp_path / "sfm"), SfmConfig(), model_dir=model)
    assert res.report["undistorted"] is True and res.report["camera_models"] == ["SIMPLE_RADIAL"]
    rec = pycolmap.Reconstruction(str(tmp_path / "sfm" / "sparse" / "0"))
    assert {c.model.name for c in rec.cameras.values()} <= {"PINHOLE", "SIMPLE_PINHOLE"}
    with pytest.raises(ValueError, match="have distortion and sfm.undistort is false"):
        run_sfm(project["images"], SfmOutputs(tmp_path / "no"), SfmConfig(undistort=False), model_dir=model)


def test_a_malformed_model_is_a_clear_error(project, tmp_path):
    model = tmp_path / "sparse" / "0"
    shutil.copytree(project["text"], model)
    (model / "images.txt").write_text("1 1 0 0 0 0 0 0 1 ring_00.png\n160 120 notanumber\n")
    with pytest.raises(SfmError, match="cannot be read"):
        run_sfm(project["images"], SfmOutputs(tmp_path / "sfm"), SfmConfig(), model_dir=model)


# ---- the scene file and the workflow --------------------------------------------------------------

def _scene(tmp_path: Path, text: str) -> Path:
    d = tmp_path / "scenes"
    d.mkdir(exist_ok=True)
    (d / "proj.yaml").write_text(text)
    return d


def test_a_colmap_scene_names_what_is_missing(project, tmp_path):
    d = _scene(tmp_path, f"source: colmap\nimages: {project['images']}\n")
    with pytest.raises(ValueError, match="source 'colmap' needs 'images: PROJECT/images' and 'sparse"):
        load_scene(d, "proj")
    d = _scene(tmp_path, f"source: colmap\nimages: {project['images']}\nsparse: {tmp_path}\n")
    with pytest.raises(FileNotFoundError, match="holds no COLMAP model"):
        load_scene(d, "proj")
    d = _scene(tmp_path, f"source: photos\nphotos: {project['images']}\nsparse: {project['text']}\n")
    with pytest.raises(ValueError, match="'images' and 'sparse' belong to source 'colmap'"):
        load_scene(d, "proj")
    # a project's sparse/ folder is taken to its model sparse/0
    d = _scene(tmp_path, f"source: colmap\nimages: {project['images']}\nsparse: {project['root'] / 'sparse'}\n")
    assert load_scene(d, "proj")["sparse"] == str(project["text"])


def test_the_workflow_has_no_capture_or_sfm_job(project, tmp_path):
    d = _scene(tmp_path, f"source: colmap\nimages: {project['images']}\nsparse: {project['text']}\n"
                         "effects: [foliage_sway]\n")
    exe = Path(sys.executable).with_name("snakemake")
    res = subprocess.run([str(exe), "-n", "--cores", "1", "all_static", "--config", f"scene_dir={d}", "scenes=[proj]",
                          f"results={tmp_path / 'results'}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    table = res.stdout.split("Job stats:", 1)[1].split("total", 1)[0]
    jobs = {line.split()[0] for line in table.splitlines()[3:] if line.strip()}
    assert jobs == {"colmap_import", "static", "all_static"}, table
