"""SfM tracks per photo: where each photo sees its triangulated points, and how far away they are.

For every registered image of a reconstruction: rows ``(x, y, depth)`` [N,3], one per SfM point
the image observes, with ``(x, y)`` the observation in the image's pixels (COLMAP's convention,
pixel centres at +0.5, the size of the sfm stage's ``cameras.json``) and ``depth`` the point's
camera-space z in the output frame (the frame of ``cameras.json``: the sfm stage writes its model
after the frame normalisation, so no transform is left to apply). The static fit's depth loss
(:mod:`anigs.static.depth`) pulls the render's expected depth towards them.

File ``tracks.npz`` (:func:`save_tracks`, atomic and byte-reproducible): ``names`` [I] str (sorted),
``offsets`` [I+1] int64 (image ``i``'s rows are ``rows[offsets[i]:offsets[i+1]]``), ``rows`` [M,3]
float32.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from anigs.io import write_npz

Tracks = dict[str, np.ndarray]  # image name -> rows (x, y, depth) [N,3] float32


def model_tracks(rec) -> Tracks:
    """Per registered image of a ``pycolmap.Reconstruction``: its observed SfM points as rows
    (x, y, depth) [N,3] float32 in observation order. Left out: points behind the camera, and
    observations outside the image (undistortion moves a few keypoints near the border out of it)."""
    out: Tracks = {}
    for image_id in rec.reg_image_ids():
        im = rec.images[image_id]
        pose = im.cam_from_world()
        R, t = np.asarray(pose.rotation.matrix()), np.asarray(pose.translation).reshape(3)
        obs = [(p.xy[0], p.xy[1], p.point3D_id) for p in im.points2D if p.has_point3D()]
        if not obs:
            out[im.name] = np.zeros((0, 3), np.float32)
            continue
        xyz = np.array([rec.points3D[pid].xyz for _, _, pid in obs], np.float64).reshape(-1, 3)
        z = xyz @ R[2] + t[2]
        rows = np.c_[np.array([(x, y) for x, y, _ in obs], np.float64), z]
        cam = rec.cameras[im.camera_id]
        keep = (z > 0) & (rows[:, 0] >= 0) & (rows[:, 0] <= cam.width) & (rows[:, 1] >= 0) & (rows[:, 1] <= cam.height)
        out[im.name] = rows[keep].astype(np.float32)
    return out


def check_tracks(tracks: Tracks, what: str = "tracks") -> Tracks:
    """``tracks`` with every array as float32 [N,3]; raises ValueError naming the image whose
    rows are not [N,3], not finite, or not in front of the camera (depth <= 0)."""
    checked: Tracks = {}
    for name, rows in tracks.items():
        rows = np.asarray(rows, np.float32)
        if rows.ndim != 2 or rows.shape[1] != 3:
            raise ValueError(f"{what}: image {name!r} has rows of shape {rows.shape}, expected [N,3] (x, y, depth)")
        if not np.isfinite(rows).all():
            raise ValueError(f"{what}: image {name!r} has {int((~np.isfinite(rows)).any(1).sum())} non-finite rows")
        if (rows[:, 2] <= 0).any():
            raise ValueError(f"{what}: image {name!r} has {int((rows[:, 2] <= 0).sum())} rows with depth <= 0")
        checked[name] = rows
    return checked


def save_tracks(path: str | Path, tracks: Tracks) -> None:
    """Write ``tracks`` (checked) to ``path`` atomically, images sorted by name (the same tracks
    always give the same bytes)."""
    tracks = check_tracks(tracks)
    names = sorted(tracks)
    counts = [len(tracks[n]) for n in names]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    rows = np.concatenate([tracks[n] for n in names]) if names else np.zeros((0, 3), np.float32)
    write_npz(path, names=np.array(names, dtype=str), offsets=offsets, rows=rows.astype(np.float32))


def load_tracks(path: str | Path) -> Tracks:
    """Read a ``tracks.npz`` (:func:`save_tracks`); raises ValueError naming the file when its
    arrays are missing or inconsistent, or its rows are not finite or behind a camera."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such tracks file (the sfm stage writes tracks.npz)")
    with np.load(path, allow_pickle=False) as z:
        missing = {"names", "offsets", "rows"} - set(z.files)
        if missing:
            raise ValueError(f"{path}: missing array(s) {sorted(missing)}")
        names, offsets, rows = z["names"], z["offsets"].astype(np.int64), z["rows"]
    if offsets.shape != (len(names) + 1,) or offsets[0] != 0 or offsets[-1] != len(rows) or (np.diff(offsets) < 0).any():
        raise ValueError(f"{path}: offsets {offsets.shape} do not index {len(rows)} rows of {len(names)} images")
    return check_tracks({str(n): rows[offsets[i]:offsets[i + 1]] for i, n in enumerate(names)}, str(path))
