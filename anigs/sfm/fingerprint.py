"""Fingerprints of the sfm stage's intermediate results: where two runs of the same photos part.

``report.json``'s ``fingerprints`` holds a short digest after each step (:func:`step_fingerprints`):
``features`` (cameras, image names and ids, keypoints and descriptors of the database), ``matches``
(raw matches and the verified two-view geometries, pair by pair in pair-id order), ``mapped``
(the kept model before refinement) and ``model`` (after it). Two runs with one ``cameras.json``
have the same four; when the cameras differ, the first digest that differs names the step
that diverged, without keeping the COLMAP database (``benchmarks/sfm_determinism.py``).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

DIGEST_CHARS = 16  # hex characters kept per digest (64 bits: enough to tell runs apart)


def _update(h, *arrays) -> None:
    for a in arrays:
        if a is None:
            h.update(b"-")
            continue
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())


def database_fingerprints(database: str | Path) -> dict[str, str]:
    """``{"features": ..., "matches": ...}`` digests of a COLMAP database (see the module docstring)."""
    import pycolmap

    feats, matches = hashlib.sha256(), hashlib.sha256()
    db = pycolmap.Database.open(str(database))
    try:
        for cam in sorted(db.read_all_cameras(), key=lambda c: c.camera_id):
            feats.update(f"{cam.camera_id} {cam.model.name} {cam.width} {cam.height}".encode())
            _update(feats, cam.params)
        for im in sorted(db.read_all_images(), key=lambda i: i.image_id):
            feats.update(f"{im.image_id} {im.name} {im.camera_id}".encode())
            _update(feats, db.read_keypoints(im.image_id), db.read_descriptors(im.image_id).data)
        pair_ids, geoms = db.read_two_view_geometries()
        for pair_id, g in sorted(zip(pair_ids, geoms), key=lambda t: t[0]):
            i, j = pycolmap.pair_id_to_image_pair(pair_id)
            matches.update(f"{i} {j} {int(g.config)}".encode())
            raw = db.read_matches(i, j) if db.exists_matches(i, j) else None
            # F, E and H are None where the configuration has none (pycolmap), not zero
            _update(matches, raw, g.inlier_matches, g.F, g.E, g.H)
    finally:
        db.close()
    return {"features": feats.hexdigest()[:DIGEST_CHARS], "matches": matches.hexdigest()[:DIGEST_CHARS]}


def model_fingerprint(rec) -> str:
    """Digest of a ``pycolmap.Reconstruction``: registered images (name, pose), cameras, 3D points."""
    h = hashlib.sha256()
    for image_id in sorted(rec.reg_image_ids()):
        im = rec.images[image_id]
        h.update(f"{image_id} {im.name} {im.camera_id}".encode())
        _update(h, im.cam_from_world().matrix())
    for camera_id in sorted(rec.cameras):
        _update(h, rec.cameras[camera_id].params)
    ids = sorted(rec.point3D_ids())
    _update(h, np.asarray(ids, np.int64), np.array([rec.points3D[i].xyz for i in ids]).reshape(-1, 3))
    return h.hexdigest()[:DIGEST_CHARS]
