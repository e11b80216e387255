"""The view policy per capture layout (anigs.views.policy): a walk keeps the paper's schedule,
other layouts face the ROI centroid at the capture's pitch with the photos' FOV at most."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.geometry import Layout
from anigs.views import ViewsConfig
from anigs.views.policy import LayoutPolicy, layout_policy
from tests._scenes import ring_cameras

UP = np.array([0.0, 0.0, 1.0])


def test_walk_keeps_the_configured_schedule():
    cams = ring_cameras(6)
    cfg = ViewsConfig(forward="camera", pitch_deg=-7.0, fov_deg=95.0)
    assert layout_policy(Layout("walk", {}), cams, UP, cfg) == LayoutPolicy("camera", -7.0, 95.0)


@pytest.mark.parametrize("kind", ["forward", "orbit"])
def test_other_layouts_face_the_roi_at_the_capture_pitch(kind):
    cams = ring_cameras(6)  # looking slightly down, FOV below 95 degrees
    pitch = float(np.median([np.degrees(np.arcsin(c.forward @ UP)) for c in cams]))
    fov = float(np.median([c.fov_x for c in cams]))
    assert pitch < 0 and fov < 95.0
    pol = layout_policy(Layout(kind, {}), cams, UP, ViewsConfig(forward="best", pitch_deg=0.0, fov_deg=95.0))
    assert pol.forward == "centroid"
    assert pol.pitch_deg == pytest.approx(pitch)
    assert pol.fov_deg == pytest.approx(fov)
    wide = layout_policy(Layout(kind, {}), cams, UP, ViewsConfig(fov_deg=95.0, match_capture_fov=False))
    assert wide.fov_deg == 95.0 and wide.pitch_deg == pytest.approx(pitch)
