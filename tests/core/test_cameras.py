"""Pinhole camera conventions and IO."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.cameras import Camera, intrinsics_from_fov, load_cameras, look_at, save_cameras


def test_look_at_conventions():
    eye, target = np.array([1.0, -2.0, 1.5]), np.array([0.0, 3.0, 0.5])
    V = look_at(eye, target)
    cam = Camera(intrinsics_from_fov(60, 64, 48), V, 64, 48)
    assert np.allclose(cam.center, eye)
    assert np.allclose(cam.forward, (target - eye) / np.linalg.norm(target - eye))
    uv, z = cam.project(np.stack([target, target + [0, 0, 1.0]]))
    assert np.allclose(uv[0], [32, 24]) and z[0] > 0
    assert uv[1, 1] < 24, "world up must appear towards the top of the image (y down)"
    assert np.allclose(cam.R @ cam.R.T, np.eye(3)) and np.isclose(np.linalg.det(cam.R), 1)


def test_fov_roundtrip_and_scaling():
    K = intrinsics_from_fov(95, 320, 240)
    cam = Camera(K, np.eye(4), 320, 240)
    assert np.isclose(cam.fov_x, 95)
    half = cam.scaled(160, 120)
    assert np.isclose(half.fov_x, 95) and np.isclose(half.K[0, 2], 80)
    with pytest.raises(ValueError):
        intrinsics_from_fov(180, 10, 10)


def test_json_roundtrip(tmp_path):
    cams = [Camera(intrinsics_from_fov(50 + i, 32, 24), look_at([i, 0, 1], [0, 5, 1]), 32, 24, f"c{i}") for i in range(3)]
    save_cameras(tmp_path / "c.json", cams)
    back = load_cameras(tmp_path / "c.json")
    assert [c.name for c in back] == ["c0", "c1", "c2"]
    assert all(np.array_equal(a.viewmat, b.viewmat) and np.array_equal(a.K, b.K) for a, b in zip(cams, back))


def test_bad_camera():
    with pytest.raises(ValueError, match="size"):
        Camera(np.eye(3), np.eye(4), 0, 10)
    with pytest.raises(ValueError, match="finite"):
        Camera(np.full((3, 3), np.nan), np.eye(4), 10, 10)
