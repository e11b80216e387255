"""A real splat from another trainer: OpenSplat 1.1.5 trained on the demo's sfm folder (the command and
figures: tests/fixtures/opensplat_demo/README.md). Imported through the cameras.json OpenSplat wrote, it
renders its held-out photo as OpenSplat's own render does; moved into each other trainer's frame with
the files that trainer writes, it is found again; in a frame nothing explains, it is refused."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from anigs.cameras import load_cameras
from anigs.formats.trainers import NERFSTUDIO_APPLIED, OPENSPLAT_BACKGROUND, gsplat_normalisation
from anigs.gaussians import load_ply
from anigs.geometry.transform import transform_gaussians
from anigs.images import load_image
from anigs.sfm.align import Similarity
from anigs.sfm.model import load_points
from anigs.ssim import psnr
from anigs.static.config import ImportConfig
from anigs.static.imported import SplatFrameError, import_splat

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "opensplat_demo"
REF = json.loads((FIX / "reference.json").read_text())
#: the user's COLMAP frame for the other trainers' tests: colmap -> sfm (as the sfm stage's report would say)
USER = Similarity(0.8, Rotation.from_euler("xyz", [-80, 15, 50], degrees=True).as_matrix(), np.array([2.0, -1.0, 0.5]))


def _moved(g, s: Similarity):
    return transform_gaussians(g, s.scale, s.R, s.t)


@pytest.fixture(scope="module")
def capture():
    """The held-out photo first (holdout_every 4 holds out photo 0 of the 4), then three training photos."""
    names = [REF["val_image"]] + sorted(p.name for p in (FIX / "sfm" / "images").glob("*.png") if p.name != REF["val_image"])
    by_name = {c.name: c for c in load_cameras(FIX / "sfm" / "cameras.json")}
    cams = [by_name[n] for n in names]
    imgs = [load_image(FIX / "sfm" / "images" / n) for n in names]
    pts, _ = load_points(FIX / "sfm" / "points.npz")
    return {"cams": cams, "imgs": imgs, "points": pts}


def _import(capture, path: Path, to_sfm: Similarity = Similarity.identity(), **kw):
    return import_splat(path, capture["imgs"], capture["cams"], capture["points"], to_sfm,
                        ImportConfig(eval_max_side=0, **kw), 4)


@pytest.fixture(scope="module")
def imported(capture):
    return _import(capture, FIX / "splat.ply")


def test_opensplat_splat_renders_its_held_out_photo_as_opensplat_did(capture, imported):
    g, rec = imported
    im = rec["imported"]
    assert im["frame"] == "cameras" and im["cameras_fit"]["matched"] == 4 and im["cameras_fit"]["listed"] == 48
    assert im["background"] == pytest.approx(list(OPENSPLAT_BACKGROUND)) and "OpenSplat" in im["background_from"]
    assert rec["holdout"] == [REF["val_image"]] and rec["image_size"] == [320, 240]
    assert rec["num_gaussians"] == REF["num_gaussians"]
    # OpenSplat's own held-out PSNR (its render of the photo at the last step), within 0.1 dB
    assert rec["test_psnr"] == pytest.approx(REF["psnr_db"], abs=0.1)
    # and the two renderers agree pixel for pixel, to 8-bit rounding and rasterizer detail
    from anigs.render import render_gaussians

    ours, _, _ = render_gaussians(g, capture["cams"][0], background=torch.tensor(OPENSPLAT_BACKGROUND))
    theirs = torch.from_numpy(load_image(FIX / "val_render.png"))
    assert psnr(ours.clamp(0, 1), theirs) > 35


@pytest.fixture(scope="module")
def in_colmap(imported):
    """The same splat in the user's COLMAP frame (INRIA 3DGS's)."""
    return _moved(imported[0], USER.inverse())


def _inria_cameras(path: Path, cams, frame: Similarity) -> None:
    out = []
    for i, c in enumerate(cams):
        c2w = np.linalg.inv(frame.apply_camera(c).viewmat)
        out.append({"id": i, "img_name": Path(c.name).stem, "width": c.width, "height": c.height,
                    "position": c2w[:3, 3].tolist(), "rotation": c2w[:3, :3].tolist(), "fx": c.K[0, 0], "fy": c.K[1, 1]})
    path.write_text(json.dumps(out))


def test_inria_layout_in_the_colmap_frame(capture, imported, in_colmap, tmp_path):
    ply = tmp_path / "point_cloud" / "iteration_1000" / "point_cloud.ply"
    ply.parent.mkdir(parents=True)
    in_colmap.save_ply(ply)
    _inria_cameras(tmp_path / "cameras.json", capture["cams"], USER.inverse())
    (tmp_path / "cfg_args").write_text("Namespace(sh_degree=3, source_path='/data/demo', white_background=False)")
    g, rec = _import(capture, ply, USER, background=tuple(OPENSPLAT_BACKGROUND))
    assert rec["imported"]["frame"] == "cameras" and rec["test_psnr"] == pytest.approx(imported[1]["test_psnr"], abs=0.1)
    # without its cameras.json, the COLMAP frame itself
    (tmp_path / "cameras.json").unlink()
    g, rec = _import(capture, ply, USER, background=tuple(OPENSPLAT_BACKGROUND))
    assert rec["imported"]["frame"] == "colmap" and rec["test_psnr"] == pytest.approx(imported[1]["test_psnr"], abs=0.1)


def test_nerfstudio_export_with_its_dataparser_transforms(capture, imported, in_colmap, tmp_path):
    T = np.c_[Rotation.from_euler("zyx", [20, -5, 3], degrees=True).as_matrix(), [0.1, 0.2, -0.3]]
    scale = 0.31
    ns = Similarity(scale, T[:, :3], scale * T[:, 3]).compose(Similarity(1.0, NERFSTUDIO_APPLIED, np.zeros(3)))
    (tmp_path / "exports" / "splat").mkdir(parents=True)
    _moved(in_colmap, ns).save_ply(tmp_path / "exports" / "splat" / "splat.ply")
    (tmp_path / "dataparser_transforms.json").write_text(json.dumps({"transform": T.tolist(), "scale": scale}))
    g, rec = _import(capture, tmp_path / "exports" / "splat" / "splat.ply", USER, background=tuple(OPENSPLAT_BACKGROUND))
    assert rec["imported"]["frame"] == "nerfstudio"
    assert rec["test_psnr"] == pytest.approx(imported[1]["test_psnr"], abs=0.1)


def test_gsplat_normalised_world(capture, imported, in_colmap, tmp_path):
    back = USER.inverse()
    c2w = np.stack([np.linalg.inv(back.apply_camera(c).viewmat) for c in capture["cams"]])
    G = gsplat_normalisation(c2w, back.apply(capture["points"]))
    s = float(np.cbrt(np.linalg.det(G[:3, :3])))
    _moved(in_colmap, Similarity(s, G[:3, :3] / s, G[:3, 3])).save_ply(tmp_path / "point_cloud_999.ply")
    g, rec = _import(capture, tmp_path / "point_cloud_999.ply", USER, background=tuple(OPENSPLAT_BACKGROUND))
    assert rec["imported"]["frame"] == "gsplat"
    assert rec["test_psnr"] == pytest.approx(imported[1]["test_psnr"], abs=0.1)


def test_the_splat_in_a_wrong_frame_is_refused(capture, tmp_path):
    """OpenSplat's splat without its cameras.json and moved by a similarity no trainer applies: every frame
    is tried and the error names them, the bar and the key."""
    odd = Similarity(1.7, Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix(), np.array([0.5, 0, 0]))
    _moved(load_ply(FIX / "splat.ply"), odd).save_ply(tmp_path / "moved.ply")
    with pytest.raises(SplatFrameError) as err:
        _import(capture, tmp_path / "moved.ply", USER)
    msg = str(err.value)
    for part in ("does not render the photos in any frame tried", "sfm [", "colmap [", "opensplat [", "gsplat [",
                 "static.imported.frame", "Trainer files found: none"):
        assert part in msg, msg
