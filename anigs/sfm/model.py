"""COLMAP models <-> project data: cameras, sparse points, similarity transforms, model folders."""
from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path

import numpy as np

from anigs.sfm.align import Similarity
from anigs.cameras import Camera
from anigs.sfm.config import UNDISTORTED_MODELS


def reconstruction_cameras(rec) -> list[Camera]:
    """Registered images of a PINHOLE-family ``pycolmap.Reconstruction`` as cameras, sorted by name."""
    cams = []
    for image_id in rec.reg_image_ids():
        im = rec.images[image_id]
        cam = rec.cameras[im.camera_id]
        if cam.model.name not in UNDISTORTED_MODELS:
            raise ValueError(f"image {im.name}: camera model {cam.model.name} has distortion; "
                             "undistort before converting (sfm.undistort)")
        V = np.eye(4)
        V[:3, :] = im.cam_from_world().matrix()
        cams.append(Camera(cam.calibration_matrix(), V, cam.width, cam.height, im.name))
    return sorted(cams, key=lambda c: c.name)


def reconstruction_points(rec) -> dict[str, np.ndarray]:
    """Sparse points: xyz [P,3] float32, rgb [P,3] float32 in [0,1], error [P], track_length [P]."""
    pts = list(rec.points3D.values())
    if not pts:
        return {"xyz": np.zeros((0, 3), np.float32), "rgb": np.zeros((0, 3), np.float32),
                "error": np.zeros(0, np.float32), "track_length": np.zeros(0, np.int32)}
    return {"xyz": np.array([p.xyz for p in pts], np.float32),
            "rgb": np.array([p.color for p in pts], np.float32) / 255.0,
            "error": np.array([p.error for p in pts], np.float32),
            "track_length": np.array([p.track.length() for p in pts], np.int32)}


def to_sim3d(s: Similarity):
    """A :class:`anigs.sfm.align.Similarity` as a ``pycolmap.Sim3d`` (for ``Reconstruction.transform``)."""
    import pycolmap

    return pycolmap.Sim3d(float(s.scale), pycolmap.Rotation3d(s.R), s.t.reshape(3, 1))


def find_model_dir(model_dir: Path) -> Path:
    """The folder holding ``cameras.bin/.txt`` (``model_dir`` itself or a project's ``sparse/0``)."""
    has_model = lambda d: any((d / f"cameras.{ext}").exists() for ext in ("bin", "txt"))
    if not has_model(model_dir) and (model_dir / "0").is_dir():
        model_dir = model_dir / "0"  # a COLMAP project's sparse/ folder
    if not has_model(model_dir):
        raise FileNotFoundError(f"no COLMAP model (cameras.bin/.txt, images, points3D) in {model_dir}")
    return model_dir


def replace_dir(src: Path, dst: Path) -> None:
    """Move a finished folder onto ``dst`` (removing an older one) with renames only."""
    old = None
    if dst.exists():
        old = dst.with_name(f".{dst.name}.old{os.getpid()}")
        os.replace(dst, old)
    os.replace(src, dst)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def load_points(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """SfM points [P,3] and colours [P,3] in [0,1] from an npz (keys xyz/rgb or points/colors)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"SfM points file not found: {path} (written by `anigs sfm`)")
    with np.load(path) as data:
        keys = set(data.files)
        pk = next((k for k in ("xyz", "points") if k in keys), None)
        ck = next((k for k in ("rgb", "colors") if k in keys), None)
        if pk is None:
            raise KeyError(f"{path}: no point array (expected key 'xyz' or 'points'; found {sorted(keys)})")
        pts = np.asarray(data[pk], dtype=np.float64)
        if ck is None:
            logging.getLogger("anigs.sfm").warning("%s has no colours ('rgb'/'colors'): initialising grey", path)
            cols = np.full_like(pts, 0.5)
        else:
            cols = np.asarray(data[ck])
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{path}: '{pk}' must be [P,3], got {pts.shape}")
    if cols.shape != pts.shape:
        raise ValueError(f"{path}: colours {cols.shape} do not match points {pts.shape}")
    cols = cols.astype(np.float64) / 255.0 if np.issubdtype(cols.dtype, np.integer) or cols.max(initial=0) > 1.5 \
        else cols.astype(np.float64)
    return pts, np.clip(cols, 0, 1)
