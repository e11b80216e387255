"""A splat trained elsewhere, imported by the static stage (anigs.static.imported): each trainer's frame
convention is found from the files it writes (or, without them, by rendering the photos), and a splat
in a frame nothing explains is refused with the frames tried.

The capture: photos of a textured scene from a ring of cameras, a COLMAP project of those cameras in a
user's frame (tests/sfm/_project.py), read by the sfm stage; the "splat" is the scene that rendered the
photos, written in each trainer's frame with the files that trainer writes beside it.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

pytest.importorskip("pycolmap")

from anigs.cameras import Camera, intrinsics_from_fov, load_cameras  # noqa: E402
from anigs.formats.trainers import (NERFSTUDIO_APPLIED, OPENGL_AXES, gsplat_normalisation,  # noqa: E402
                                    opensplat_normalisation, trainer_files)
from anigs.gaussians import Gaussians  # noqa: E402
from anigs.geometry.transform import transform_gaussians  # noqa: E402
from anigs.images import load_inputs  # noqa: E402
from anigs.sfm.align import Similarity  # noqa: E402
from anigs.sfm.colmap import SfmConfig, run_sfm  # noqa: E402
from anigs.sfm.model import load_points  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402
from anigs.static.config import ImportConfig  # noqa: E402
from anigs.static.imported import SplatFrameError, background, import_splat, sfm_frame  # noqa: E402
from tests.sfm._captures import H, W, ring_positions, textured_boxes  # noqa: E402
from tests.sfm._project import USER_FRAME, colmap_project  # noqa: E402

CFG = ImportConfig(background=(0.5, 0.5, 0.5))  # the photos were rendered onto grey
HOLDOUT = 4  # photos 0, 4, 8 held out


def _moved(g: Gaussians, s: Similarity) -> Gaussians:
    return transform_gaussians(g, s.scale, s.R, s.t)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    root = tmp_path_factory.mktemp("capture")
    K = intrinsics_from_fov(60, W, H)
    cams = [Camera(K, v, W, H, f"ring_{k:02d}.png") for k, v in enumerate(ring_positions(10))]
    scene = textured_boxes(0, 1500, 300)
    project = colmap_project(root, cams, scene)
    out = SfmOutputs(root / "sfm")
    run_sfm(project["images"], out, SfmConfig(), model_dir=project["text"])
    imgs, sfm_cams = load_inputs(out.path("images"), out.path("cameras"), compact=True)
    pts, _ = load_points(out.path("points"))
    to_sfm = sfm_frame(out.path("report"))
    user = _moved(scene, USER_FRAME)  # the splat as INRIA 3DGS would write it: the COLMAP project's frame
    user_cams = [USER_FRAME.apply_camera(c) for c in cams]
    return {"root": root, "images": [i.numpy() for i in imgs], "cams": sfm_cams, "points": pts, "to_sfm": to_sfm,
            "user": user, "user_cams": user_cams, "user_points": _model_points(project["text"]),
            "reference": _moved(user, to_sfm)}


def _model_points(model: Path) -> np.ndarray:
    """[P,3] the points of the COLMAP model (what gsplat's parser normalises with)."""
    import pycolmap

    return np.array([p.xyz for p in pycolmap.Reconstruction(str(model)).points3D.values()])


def _import(capture, path: Path, cfg: ImportConfig = CFG):
    return import_splat(path, capture["images"], capture["cams"], capture["points"], capture["to_sfm"], cfg, HOLDOUT)


@pytest.fixture(scope="module")
def reference(capture, tmp_path_factory):
    """The scene written in the sfm folder's frame (a trainer run on anigs's sfm folder): the figures every
    convention below must reproduce."""
    path = tmp_path_factory.mktemp("sfm_frame") / "splat.ply"
    capture["reference"].save_ply(path)
    g, rec = _import(capture, path)
    assert rec["imported"]["frame"] == "sfm"
    assert rec["test_psnr"] > 30 and rec["test_views"] == 3 and rec["train_views"] == 7
    return rec


def _cameras_json(path: Path, cams: list[Camera], frame: Similarity, axes: np.ndarray, stems: bool) -> None:
    """An INRIA-layout cameras.json of ``cams`` (their frame) taken into ``frame``, rotations in ``axes``."""
    out = []
    for i, c in enumerate(cams):
        c2w = np.linalg.inv(frame.apply_camera(c).viewmat)
        out.append({"id": i, "img_name": Path(c.name).stem if stems else c.name, "width": c.width,
                    "height": c.height, "position": c2w[:3, 3].tolist(), "rotation": (c2w[:3, :3] @ axes).tolist(),
                    "fx": c.K[0, 0], "fy": c.K[1, 1]})
    path.write_text(json.dumps(out))


def _same(rec: dict, reference: dict) -> None:
    assert rec["test_psnr"] == pytest.approx(reference["test_psnr"], abs=0.1)
    assert rec["train_psnr"] == pytest.approx(reference["train_psnr"], abs=0.1)


def test_inria_run_folder_in_the_colmap_frame(capture, reference, tmp_path):
    """INRIA 3DGS: point_cloud/iteration_30000/point_cloud.ply, cameras.json and cfg_args two folders up."""
    ply = tmp_path / "point_cloud" / "iteration_30000" / "point_cloud.ply"
    ply.parent.mkdir(parents=True)
    capture["user"].save_ply(ply)
    _cameras_json(tmp_path / "cameras.json", capture["user_cams"], Similarity.identity(), np.eye(3), stems=True)
    (tmp_path / "cfg_args").write_text("Namespace(data_device='cuda', eval=True, images='images', model_path='out', "
                                       "resolution=-1, sh_degree=3, source_path='/data/garden', white_background=True)")
    g, rec = _import(capture, ply)
    im = rec["imported"]
    assert im["frame"] == "cameras" and im["cameras_fit"]["matched"] == 10 and im["cameras_fit"]["axes"] == "opencv"
    assert len(im["trainer_files"]) == 2
    assert torch.allclose(g.means, capture["reference"].means, atol=1e-4)
    _same(rec, reference)
    # the trainer's background (static.imported.background: trainer) is what its cfg_args says
    assert background(ImportConfig(), trainer_files(ply)) == ((1.0, 1.0, 1.0), f"{tmp_path / 'cfg_args'} white_background")


def test_a_bare_splat_in_the_colmap_frame(capture, reference, tmp_path):
    """No file beside it: the COLMAP project's frame is found by rendering the photos."""
    capture["user"].save_ply(tmp_path / "splat.ply")
    g, rec = _import(capture, tmp_path / "splat.ply")
    assert rec["imported"]["frame"] == "colmap" and rec["imported"]["trainer_files"] == []
    _same(rec, reference)


def _opensplat(capture) -> Similarity:
    """OpenSplat 1.1.5's frame (autoScaleAndCenterPoses): camera centres about their mean, the largest
    coordinate scaled to 1."""
    centres = np.stack([c.center for c in capture["user_cams"]])
    centre, f = opensplat_normalisation(centres)
    assert np.abs((centres - centre) * f).max() == pytest.approx(1.0)
    return Similarity(f, np.eye(3), -centre * f)


def test_opensplat_frame_from_its_cameras_json(capture, reference, tmp_path):
    """OpenSplat writes its cameras.json (img_name with the extension, OpenCV rotations) in its frame;
    here the rotations are written in OpenGL camera axes too, as nerfstudio-style trainers keep them."""
    own = _opensplat(capture)
    _moved(capture["user"], own).save_ply(tmp_path / "splat.ply")
    for axes, name in ((np.eye(3), "opencv"), (OPENGL_AXES, "opengl")):
        _cameras_json(tmp_path / "cameras.json", capture["user_cams"], own, axes, stems=False)
        g, rec = _import(capture, tmp_path / "splat.ply")
        fit = rec["imported"]["cameras_fit"]
        assert rec["imported"]["frame"] == "cameras" and fit["axes"] == name and fit["rotation_residual_deg"] < 1e-6
        _same(rec, reference)


def test_opensplat_frame_without_its_cameras_json(capture, reference, tmp_path):
    _moved(capture["user"], _opensplat(capture)).save_ply(tmp_path / "splat.ply")
    g, rec = _import(capture, tmp_path / "splat.ply")
    assert rec["imported"]["frame"] == "opensplat"
    _same(rec, reference)


def test_nerfstudio_dataparser_transforms(capture, reference, tmp_path):
    """ns-export gaussian-splat: the splat in the dataparser's frame, dataparser_transforms.json in the run's
    folder (one up), applied after nerfstudio's COLMAP axes (x, z, -y)."""
    T = np.c_[Rotation.from_euler("z", 30, degrees=True).as_matrix(), [0.3, -0.2, 0.1]]
    scale = 0.17
    ns = Similarity(scale, T[:, :3], scale * T[:, 3]).compose(Similarity(1.0, NERFSTUDIO_APPLIED, np.zeros(3)))
    (tmp_path / "exports").mkdir()
    _moved(capture["user"], ns).save_ply(tmp_path / "exports" / "splat.ply")
    (tmp_path / "dataparser_transforms.json").write_text(json.dumps({"transform": T.tolist(), "scale": scale}))
    g, rec = _import(capture, tmp_path / "exports" / "splat.ply")
    assert rec["imported"]["frame"] == "nerfstudio" and "COLMAP axes" in rec["imported"]["frame_source"]
    _same(rec, reference)


def test_gsplat_normalised_world(capture, reference, tmp_path):
    """gsplat's simple_trainer (normalize_world_space) writes no file: its similarity is recomputed from the
    COLMAP cameras and points and confirmed by rendering."""
    c2w = np.stack([np.linalg.inv(c.viewmat) for c in capture["user_cams"]])
    G = gsplat_normalisation(c2w, capture["user_points"])
    s = float(np.cbrt(np.linalg.det(G[:3, :3])))
    _moved(capture["user"], Similarity(s, G[:3, :3] / s, G[:3, 3])).save_ply(tmp_path / "ckpt_29999.ply")
    g, rec = _import(capture, tmp_path / "ckpt_29999.ply")
    assert rec["imported"]["frame"] == "gsplat"
    _same(rec, reference)


def test_a_splat_in_an_unexplained_frame_is_refused(capture, reference, tmp_path):
    odd = Similarity(0.4, Rotation.from_euler("xyz", [40, 10, -60], degrees=True).as_matrix(), np.array([1.0, 2, 3]))
    _moved(capture["reference"], odd).save_ply(tmp_path / "splat.ply")
    with pytest.raises(SplatFrameError) as err:
        _import(capture, tmp_path / "splat.ply")
    msg = str(err.value)
    for part in ("does not render the photos in any frame tried", "Tried: sfm", "colmap [", "gsplat [",
                 "static.imported.frame", "Trainer files found: none"):
        assert part in msg, msg
    best = float(msg.split("best ", 1)[1].split(" dB")[0])
    assert best < reference["imported"]["bar_db"]


def test_a_forced_frame_that_does_not_fit_is_refused(capture, tmp_path):
    capture["user"].save_ply(tmp_path / "splat.ply")
    with pytest.raises(SplatFrameError, match=r"Tried: gsplat \[.*\]"):
        _import(capture, tmp_path / "splat.ply", ImportConfig(frame="gsplat", background=(0.5, 0.5, 0.5)))
    with pytest.raises(SplatFrameError, match="nothing beside the splat gives that frame"):
        _import(capture, tmp_path / "splat.ply", ImportConfig(frame="nerfstudio", background=(0.5, 0.5, 0.5)))


def test_cameras_of_another_capture_are_named(capture, tmp_path):
    capture["user"].save_ply(tmp_path / "splat.ply")
    others = [Camera(c.K, c.viewmat, c.width, c.height, f"DSC_{i:04d}.JPG") for i, c in enumerate(capture["user_cams"])]
    _cameras_json(tmp_path / "cameras.json", others, Similarity.identity(), np.eye(3), stems=True)
    with pytest.raises(SplatFrameError, match=r"0 of its 10 photos are named as in the sfm folder .*another capture"):
        _import(capture, tmp_path / "splat.ply")


def test_a_nan_in_the_splat_names_the_file(capture, tmp_path):
    bad = capture["user"].detach()
    bad.means[3, 1] = math.nan
    bad.save_ply(tmp_path / "splat.ply")
    with pytest.raises(ValueError, match=r"imported splat .*splat.ply: parameter 'means' has non-finite values in 1"):
        _import(capture, tmp_path / "splat.ply")


def test_the_stage_writes_the_static_folder(capture, tmp_path):
    """``anigs static --splat``: canonical.ply in the sfm frame, metrics.json with the PSNRs and the frame,
    fit.png (photo, render, error); no fit ran."""
    from anigs.stages import static as stage

    capture["user"].save_ply(tmp_path / "splat.ply")
    sfm = capture["root"] / "sfm"
    out = stage.Outputs(tmp_path / "static")
    stage.run(stage.Inputs(images=sfm / "images", cameras=sfm / "cameras.json", points=sfm / "points.npz",
                           out=out, splat=tmp_path / "splat.ply", report=sfm / "report.json"),
              stage.Config.from_dict({"holdout_every": HOLDOUT, "imported": {"background": [0.5, 0.5, 0.5]}}))
    m = out.metrics()
    assert m["imported"]["frame"] == "colmap" and m["iterations"] == 0 and m["accuracy"]["warning"] is None
    assert m["num_gaussians"] == capture["user"].num and m["sh_degree"] == capture["user"].sh_degree
    assert out.canonical().num == capture["user"].num
    assert out.path("fit").stat().st_size > 10_000
    assert [c.name for c in load_cameras(sfm / "cameras.json")][0] == "ring_00.png"
