"""The content figure of a view (anigs.views.content): sky needles and blur fail, content passes."""
from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.synth.floaters import with_floaters
from anigs.views import ViewsConfig, plan_views, scene_coverage
from anigs.views.content import (content_fraction, edge_share, footprint_ratio, render_rgb,
                                 sharp_gaussians)
from anigs.views.coverage import observation_counts
from anigs.synth.scene import SKY
from tests.masks.test_lift import toy_scene

#: the views stage's content rule, with its two gates recorded, not applied (what these tests measure)
RULE = dataclasses.replace(ViewsConfig().content_rule(), min_motion_sharpness=0.0, max_unobserved=1.0)


@pytest.fixture(scope="module")
def needled():
    """The toy scene (ground, wall, three textured blobs; a ring of 8 photos) with sky needles
    and huge blobs 2 m above its top, and its sharp-Gaussian set."""
    gs, lab, cams = toy_scene(ring=8)
    g, flo = with_floaters(gs, seed=0, needles=200, blobs=10, height=2.0)
    pts = gs.means.numpy()[::4]
    return g, flo, cams, pts, sharp_gaussians(g, cams, RULE, pts)


def _cam(eye, target, w=96, h=72) -> Camera:
    return Camera(intrinsics_from_fov(60, w, h), look_at(eye, target), w, h, "v")


def test_sky_needles_are_not_sharp_and_scene_gaussians_are(needled):
    g, flo, cams, pts, ss = needled
    assert not ss.sharp[flo].any()
    seen = ss.observations[~flo] >= 2
    assert ss.sharp[~flo][seen].mean() > 0.9


def test_a_view_of_needled_sky_fails_that_the_coverage_rule_passes(needled):
    g, flo, cams, pts, ss = needled
    sky = _cam((0.0, -4.0, 1.5), (0.0, 0.0, 3.2))       # looks up at the needles
    scene = _cam((0.0, -4.0, 1.5), (-0.3, 0.0, 0.6))    # looks at the blobs and the wall
    obs = observation_counts(g, cams)
    g_obs = g.subset(torch.from_numpy(np.nonzero(obs >= 2)[0]))
    assert scene_coverage(g_obs, sky) >= 0.8           # the needles are seen from everywhere
    assert content_fraction(g, ss.sharp, sky) < 0.2
    assert content_fraction(g, ss.sharp, scene) >= ViewsConfig().min_content
    # the image figure does not see it: the needles are thin and crisp across, full of edges
    assert edge_share(render_rgb(g, sky, SKY)) > 0.5


def test_footprint_ratio_flags_a_blob_among_small_neighbours():
    gs, _, _ = toy_scene(ring=4)
    g = gs.detach()
    g.log_scales[100] += math.log(20.0)
    r = footprint_ratio(g)
    assert r[100] > 10 and np.median(r) == pytest.approx(1.0, abs=0.2)


def test_edge_share_separates_texture_blur_and_sky():
    rng = np.random.default_rng(0)
    tex = rng.uniform(0, 1, (96, 128, 3)).astype(np.float32)
    blur = cv2.GaussianBlur(tex, (0, 0), 8)
    sky = np.broadcast_to(np.array(SKY, np.float32), (96, 128, 3))
    assert edge_share(tex) > 0.95
    assert edge_share(blur) < 0.3
    assert edge_share(sky) == 0.0
    half = sky.copy()
    half[48:] = tex[48:]
    assert 0.5 < edge_share(half) < 0.6             # the textured half plus 4 px above it
    assert edge_share((half * 255).astype(np.uint8)) == pytest.approx(edge_share(half), abs=0.02)


def test_the_plan_replaces_needled_sky_views_and_records_why(needled):
    g, flo, cams, pts, _ = needled
    base = dict(layout="walk", width=64, height=48, num_locations=3, fov_deg=60.0, forward="centroid",
                pitch_deg=35.0, max_pitch_drop_deg=40.0)
    old = plan_views(g, np.ones(g.num, bool), cams, ViewsConfig(**base, min_content=0.0), keep_all="whole scene",
                     points=pts)
    new = plan_views(g, np.ones(g.num, bool), cams, ViewsConfig(**base), keep_all="whole scene", points=pts)
    assert min(v["content"] for v in old.views) < 0.5  # without the test, a sky view is queued
    assert new.views and all(v["content"] >= 0.5 for v in new.views)
    assert any("content" in r["reason"] and r["content"] < 0.5 for r in new.rejected)
    data = new.to_json()
    assert data["content"]["per_view"] == [v["content"] for v in new.views]
    assert len(data["content"]["edge_share_per_view"]) == len(new.views)
    # the directions rejected for their content are drawn in their own colour on the top-down map
    from anigs.views.topdown import _NO_CONTENT, draw_topdown

    img = draw_topdown(new, g.means.numpy(), np.ones(g.num, bool))
    assert (img == np.array(_NO_CONTENT, np.uint8)).all(-1).sum() > 10
    assert not (draw_topdown(old, g.means.numpy(), np.ones(g.num, bool)) == np.array(_NO_CONTENT, np.uint8)).all(-1).any()


def test_config_validation():
    with pytest.raises(ValueError, match="min_content"):
        ViewsConfig(min_content=1.5)
    with pytest.raises(ValueError, match="background"):
        ViewsConfig(background=[0, 0])
    with pytest.raises(ValueError, match="sharp_fraction"):
        ViewsConfig(sharp_fraction=0)


def test_a_view_closer_than_any_photo_shows_magnified_content_and_fails(needled):
    """A view 0.7 m from the wall that the photos see from >= 1.7 m: every pixel is dominated by
    sharp Gaussians (the figure without the resolution term passes it), but the view samples them
    ~3x finer than the best photo, so it shows their blur. A view that is one of the photos
    magnifies nothing it shows and passes."""
    from anigs.views.content import ContentCheck, magnified, pixel_footprint

    g, flo, cams, pts, ss = needled
    rule = RULE
    close = _cam((1.9, 0.0, 1.0), (2.6, 0.0, 1.0))
    assert content_fraction(g, ss.sharp, close) > 0.9  # today's figure: all sharp content
    check = ContentCheck(g, ss, rule, SKY)
    fig = check.measure(close)
    assert fig["content"] < 0.1 and fig["magnified"] > 0.9
    assert "max_sampling_ratio" in check.failure(fig)
    photo = check.measure(cams[0])
    assert photo["magnified"] == 0.0
    assert photo["content"] >= rule.min_content and check.failure(photo) is None
    # the term alone: the wall's best photo footprint is ~3x the close view's
    wall = (np.abs(g.means[:, 0].numpy() - 2.6) < 1e-6) & ss.sharp
    r = ss.photo_footprint[wall] / pixel_footprint(g, close)[wall]
    assert 2.5 < np.median(r) < 4.5
    assert magnified(g, ss.photo_footprint, close, 2.0)[wall].mean() > 0.9  # a looser limit than the default (1)
    assert magnified(g, ss.photo_footprint, close, 5.0)[wall].mean() < 0.2
    assert not magnified(g, ss.photo_footprint, close, 0.0).any()  # 0: off
    # off, the figure is the one without the term
    assert content_fraction(g, ss.sharp, close, photo_footprint=ss.photo_footprint,
                            max_sampling_ratio=0.0) == content_fraction(g, ss.sharp, close)


def test_photo_footprint_is_the_finest_of_the_photos_that_see_a_gaussian(needled):
    from anigs.views.content import pixel_footprint

    g, flo, cams, pts, ss = needled
    per_cam = np.stack([pixel_footprint(g, c) for c in cams])  # [C,N]
    seen = np.isfinite(ss.photo_footprint)
    assert (ss.observations[~seen] == 0).all() and (ss.observations[seen] > 0).all()
    assert (ss.photo_footprint[seen] >= per_cam.min(0)[seen] - 1e-12).all()
    assert (ss.photo_footprint[seen] <= per_cam.max(0)[seen] + 1e-12).all()
    with pytest.raises(ValueError, match="max_sampling_ratio"):
        ViewsConfig(max_sampling_ratio=-1)
    assert ViewsConfig(max_sampling_ratio=3).content_rule().max_sampling_ratio == 3
