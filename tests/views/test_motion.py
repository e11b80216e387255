"""The moving region's sharpness against the photos (anigs.views.motion), the photo-pose fallback and
its advice (anigs.views.fallback): blur and magnification fail, a view where a photo stood passes."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
from anigs.images import write_rgb_png
from anigs.views import ViewsConfig, plan_views
from anigs.views.content import render_rgb
from anigs.views.motion import MIN_REGION_PX, MotionSharpness, band_sharpness, moving_and_holes, photo_pose_view
from tests.masks.test_lift import toy_scene

BG = (0.5, 0.5, 0.5)


def _texture(seed: int = 0, size: int = 96) -> np.ndarray:
    """float [size,size,3]: a sharp random texture (noise with a little blur), in [0,1]."""
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.uniform(0, 1, (size, size, 3)).astype(np.float32), (0, 0), 0.6)
    return np.clip(img, 0, 1)


def test_band_sharpness_falls_with_blur_and_ignores_contrast():
    img, mask = _texture(), np.ones((96, 96), bool)
    sharp = band_sharpness(img, mask)
    assert band_sharpness(cv2.GaussianBlur(img, (0, 0), 3.0), mask) < 0.4 * sharp
    assert band_sharpness(0.2 + 0.3 * img, mask) == pytest.approx(sharp, rel=1e-3)
    assert band_sharpness((img * 255).astype(np.uint8), mask) == pytest.approx(sharp, rel=0.02)
    small = np.zeros((96, 96), bool)
    small.flat[:MIN_REGION_PX - 1] = True
    assert band_sharpness(img, small) is None
    assert band_sharpness(np.full((96, 96, 3), 0.3, np.float32), mask) is None  # no detail at all


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The toy scene, its blobs as the moving region, and its ring of photos rendered to PNGs."""
    g, lab, cams = toy_scene(ring=8)
    g = g.detach()
    roi = lab == 4
    folder = tmp_path_factory.mktemp("photos")
    for i, cam in enumerate(cams):
        cam.name = f"p{i}.png"
        write_rgb_png(folder / cam.name, render_rgb(g, cam, BG))
    save_cameras(folder / "cameras.json", cams)
    return g, roi, cams, folder


def test_a_view_where_a_photo_stood_is_as_sharp_as_the_photo(scene):
    g, roi, cams, folder = scene
    ms = MotionSharpness(g, roi, cams, folder, 192)
    assert len(ms.photos) >= len(cams) - 2  # those that show the blobs (>= MIN_REGION_PX px)
    cam = photo_pose_view(ms.photos[0].camera, 96, 72)
    fig = ms.measure(cam, render_rgb(g, cam, BG))
    assert fig["motion_sharpness"] == pytest.approx(1.0, abs=0.1)
    assert fig["motion_reference"] == cam.name and fig["motion_scale"] == pytest.approx(1.0, abs=1e-6)


def test_magnified_and_blurred_moving_regions_fail(scene):
    g, roi, cams, folder = scene
    ms = MotionSharpness(g, roi, cams, folder, 192)
    centre = g.means.detach().numpy()[roi].mean(0)
    # 5x closer to a blob than the photos (4.5 m): the view magnifies what they resolved
    eye = np.array([-1.2, 1.0, 1.0]) + np.array([0.0, -0.9, 0.1])
    near = Camera(intrinsics_from_fov(60, 96, 72), look_at(eye, (-1.2, 1.0, 1.0)), 96, 72, "near")
    fig = ms.measure(near, render_rgb(g, near, BG))
    assert fig["motion_scale"] > 2.0 and fig["motion_sharpness"] < 0.7
    # a coarse fit of the blobs (4x their scale) seen from a photo's pose
    coarse = g.detach()
    coarse.log_scales[torch.from_numpy(roi)] += float(np.log(4.0))
    ms_coarse = MotionSharpness(coarse, roi, cams, folder, 192)
    cam = photo_pose_view(ms.photos[0].camera, 96, 72)
    assert ms_coarse.measure(cam, render_rgb(coarse, cam, BG))["motion_sharpness"] < 0.7
    assert np.isfinite(centre).all()


def test_holes_count_the_pixels_no_gaussian_covers(scene):
    g, roi, cams, _ = scene
    up = Camera(intrinsics_from_fov(60, 96, 72), look_at((0.0, -4.5, 1.5), (0.0, 0.0, 6.0)), 96, 72, "sky")
    moving, holes = moving_and_holes(g, roi, up)
    assert holes.mean() > 0.3 and not (moving & holes).any()


def test_no_sharp_view_anywhere_falls_back_to_photo_poses_with_advice(scene):
    g, roi, cams, folder = scene
    cfg = ViewsConfig(num_locations=2, directions=[0.0], width=96, height=72, fov_deg=60.0, extra_locations=1,
                      min_content=0.0, min_coverage=0.0, min_motion_sharpness=5.0)  # no view can pass
    plan = plan_views(g, roi, cams, cfg, images=folder)
    assert plan.views and all(v.get("photo_pose") for v in plan.views)
    assert plan.motion is not None and "no view shows the moving region" in plan.motion["advice"]
    assert plan.motion["photo_poses"] == [v["photo_pose"] for v in plan.views]
    data = plan.to_json()
    assert data["motion"]["advice"] == plan.motion["advice"] and len(data["motion"]["per_view"]) == len(plan.views)
    # a bar every view meets: the placed views stay, nothing is said
    ok = plan_views(g, roi, cams, ViewsConfig(**{**cfg.__dict__, "min_motion_sharpness": 0.0}), images=folder)
    assert ok.motion is None and not any(v.get("photo_pose") for v in ok.views)
    assert all(v["motion_sharpness"] is not None for v in ok.views)


def test_the_whole_scene_fallback_judges_holes_not_motion(scene):
    g, roi, cams, folder = scene
    cfg = ViewsConfig(num_locations=2, directions=[0.0], width=96, height=72, fov_deg=60.0, extra_locations=1,
                      min_content=0.0, min_coverage=0.0, min_motion_sharpness=5.0)
    plan = plan_views(g, np.ones_like(roi), cams, cfg, keep_all="roi_fallback: the ROI is the whole scene",
                      images=folder)
    assert plan.motion is None and plan.views and not any(v.get("photo_pose") for v in plan.views)
    assert plan.content_rule["min_motion_sharpness"] == 0.0 and all("unobserved" in v for v in plan.views)
