"""The dense start from plane-sweep stereo (anigs.static.stereo_points): on photos of a textured wall, the
points it keeps lie on the wall, for a sideways walk and for a camera that walks along its own axis (where a
rectified stereo pair would degenerate); photos of a wall without texture give no points."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.static.stereo_points import StereoConfig, stereo_points

W, H = 240, 180
WALL_Y = 6.0  # the wall is the plane y = 6, facing the cameras


def _texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.random((200, 200, 3))  # one random colour per 0.08 m square (about 3 px at 6 m)


def _photo(cam: Camera, tex: np.ndarray | None, ss: int = 4) -> np.ndarray:
    """uint8 [H,W,3]: the wall y = WALL_Y seen by ``cam`` (each pixel's ray meets it), textured by ``tex``
    (a random colour per 0.08 m square) or flat grey; rendered at ``ss`` x the size and area-averaged, as a
    lens and a sensor do (a photo of point samples aliases, and no stereo method matches aliasing)."""
    if tex is None:
        return np.full((cam.height, cam.width, 3), 128, np.uint8)
    v, u = np.indices((cam.height * ss, cam.width * ss), dtype=np.float64) / ss
    d = np.stack([(u + 0.5 / ss - cam.K[0, 2]) / cam.K[0, 0], (v + 0.5 / ss - cam.K[1, 2]) / cam.K[1, 1],
                  np.ones_like(u)], -1)
    R, t = cam.viewmat[:3, :3], cam.viewmat[:3, 3]
    centre, rays = -R.T @ t, d @ R
    s = (WALL_Y - centre[1]) / rays[..., 1]
    P = centre + s[..., None] * rays
    i = np.floor(P[..., 0] / 0.08).astype(int) % tex.shape[0]
    j = np.floor(P[..., 2] / 0.08).astype(int) % tex.shape[1]
    return (cv2.resize(tex[i, j], (cam.width, cam.height), interpolation=cv2.INTER_AREA) * 255).astype(np.uint8)


def _cams(eyes: list[tuple[float, float, float]], look: tuple[float, float, float]) -> list[Camera]:
    K = intrinsics_from_fov(60.0, W, H)
    return [Camera(K, look_at(e, np.add(e, look)), W, H, f"{k:02d}.png") for k, e in enumerate(eyes)]


def _wall_points(n: int = 50) -> np.ndarray:
    rng = np.random.default_rng(1)
    return np.c_[rng.uniform(-3, 3, n), np.full(n, WALL_Y), rng.uniform(0, 3, n)]


@pytest.mark.parametrize("walk", ["sideways", "along the axis"])
def test_the_points_lie_on_the_wall(walk):
    if walk == "sideways":
        cams = _cams([(x, 0.0, 1.5) for x in (-0.6, -0.3, 0.0, 0.3, 0.6)], (0.0, 1.0, 0.0))
    else:  # walking towards the wall, as a camera walking down a street sees what lies ahead
        cams = _cams([(0.0, y, 1.5) for y in (0.0, 0.4, 0.8, 1.2, 1.6)], (0.0, 1.0, 0.0))
    tex = _texture()
    rec = stereo_points([_photo(c, tex) for c in cams], cams, _wall_points(), cfg=StereoConfig(max_side=240))
    assert rec.points > 2000, rec.as_dict()
    off = np.abs(rec.xyz[:, 1] - WALL_Y)
    assert np.median(off) < 0.02 * WALL_Y and np.mean(off < 0.05 * WALL_Y) > 0.95, np.percentile(off, [50, 90, 99])
    assert rec.rgb.shape == rec.xyz.shape and 0 <= rec.rgb.min() and rec.rgb.max() <= 1


def test_a_wall_without_texture_gives_no_points():
    cams = _cams([(x, 0.0, 1.5) for x in (-0.3, 0.0, 0.3)], (0.0, 1.0, 0.0))
    rec = stereo_points([_photo(c, None) for c in cams], cams, _wall_points())
    assert rec.points == 0


def test_the_budget_keeps_an_even_subsample_and_the_result_is_deterministic():
    cams = _cams([(x, 0.0, 1.5) for x in (-0.3, 0.0, 0.3)], (0.0, 1.0, 0.0))
    photos = [_photo(c, _texture()) for c in cams]
    a = stereo_points(photos, cams, _wall_points(), max_points=500)
    b = stereo_points(photos, cams, _wall_points(), max_points=500)
    assert a.points == 500 and np.array_equal(a.xyz, b.xyz) and np.array_equal(a.rgb, b.rgb)
