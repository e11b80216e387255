"""A synthetic sparse capture with sky floaters gets no view of sky (issue 29).

The capture: 11 photos walking along the courtyard's facade, looking up at it
(:func:`anigs.synth.floaters.sparse_capture_config`); the model: its ground truth plus the sky
needles and blobs a fit of such a capture leaves above it (:func:`anigs.synth.floaters.with_floaters`),
seen by every photo. A view "of sky" is one where more than half of the pixels show no part of
the real scene (ground-truth alpha < 0.5). The coverage rule alone queues such views; the
content test does not.
"""
from __future__ import annotations

import numpy as np
import pytest

from anigs.render.visibility import render_depth
from anigs.synth.capture import camera_path
from anigs.synth.floaters import sparse_capture_config, with_floaters
from anigs.synth.build import build_scene
from anigs.views import ViewsConfig, plan_views

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("one_thread")]


def _sky_share(gt, cam) -> float:
    _, alpha = render_depth(gt, cam)
    return float((alpha < 0.5).mean())


def test_sparse_capture_with_sky_floaters_gets_no_view_of_sky():
    cfg = sparse_capture_config(num_gaussians=30000, width=320, height=240)
    gt = build_scene(cfg)
    cams = camera_path(cfg.capture, cfg.seed)
    assert len(cams) == 11
    g, floaters = with_floaters(gt, seed=0, needles=400, blobs=40)
    points = gt.means.numpy()[::10]          # SfM finds points on the scene, none in the sky
    common = dict(num_locations=3, background=list(cfg.capture.background), width=128, height=96)
    fallback = "roi_fallback: the ROI is the whole scene"
    old = plan_views(g, np.ones(g.num, bool), cams, ViewsConfig(**common, min_content=0.0), keep_all=fallback,
                     points=points)
    assert max(_sky_share(gt, c) for c in old.cameras) > 0.5   # the coverage rule alone queues sky
    new = plan_views(g, np.ones(g.num, bool), cams, ViewsConfig(**common), keep_all=fallback, points=points)
    assert new.views
    shares = [_sky_share(gt, c) for c in new.cameras]
    assert max(shares) <= 0.5, shares
    assert all(v["content"] >= ViewsConfig().min_content for v in new.views)
