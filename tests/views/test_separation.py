"""Directions queued at one location are distinct views (``views.min_separation_deg``).

On the street walk every planned yaw at the first location failed its tests and fell back toward the
region of interest, to the same best direction: three near-copies of one view (94-99% overlap). With
the separation a replacement closer than the angle to a direction queued there is skipped.
"""
from __future__ import annotations

import numpy as np
import pytest

from anigs.views.config import ViewsConfig
from anigs.views.coverage import rel_deg
from anigs.views.place import Placer, _angle_deg
from anigs.views.policy import LayoutPolicy


class _Cam:
    forward = np.array([1.0, 0.0, 0.0])


class _PassingCheck:
    def failure(self, fig):
        return None


def _placer(cfg: ViewsConfig, passes) -> Placer:
    """A Placer at one candidate facing +x, the ROI straight ahead (yaw 0); a direction passes when
    ``passes(yaw, pitch)``."""
    pl = Placer(g_obs=None, check=_PassingCheck(), cand=np.zeros((1, 3)), heading=np.zeros(1),
                centroid=np.array([10.0, 0.0, 0.0]), up=np.array([0.0, 0.0, 1.0]),
                policy=LayoutPolicy("best", 0.0, 95.0), cfg=cfg)

    def coverage_of(ci, yaw, pitch):
        ok = passes(rel_deg(yaw), pitch)
        return _Cam(), (1.0 if ok else 0.0), ({"content": 1.0} if ok else None)

    pl.coverage_of = coverage_of
    return pl


def _near_roi(yaw: float, pitch: float) -> bool:  # only directions within 20 deg of the ROI pass
    return abs(yaw) <= 20.0


def test_replacements_that_copy_a_queued_view_are_skipped():
    cfg = ViewsConfig()
    slots, _ = _placer(cfg, _near_roi).place_all([0], [])
    assert [s.requested_yaw for s in slots] == [0.0]  # +-90 fell back near 0: not queued again
    dirs = [(s.placed.yaw, s.placed.pitch) for s in slots]
    assert all(_angle_deg(*a, *b) >= cfg.min_separation_deg for i, a in enumerate(dirs) for b in dirs[:i])


def test_without_the_separation_the_copies_come_back():
    slots, _ = _placer(ViewsConfig(min_separation_deg=0.0), _near_roi).place_all([0], [])
    assert len(slots) == 3
    dirs = [(s.placed.yaw, s.placed.pitch) for s in slots]
    assert max(_angle_deg(*dirs[0], *d) for d in dirs[1:]) < 30.0


def test_distinct_planned_directions_all_stay():
    slots, _ = _placer(ViewsConfig(), lambda y, p: True).place_all([0], [])
    assert sorted(s.placed.yaw for s in slots) == [-90.0, 0.0, 90.0]


def test_angle_between_directions():
    assert _angle_deg(0, 0, 90, 0) == pytest.approx(90.0)
    assert _angle_deg(10, -10, 10, -40) == pytest.approx(30.0)
    assert _angle_deg(179, 0, -179, 0) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="min_separation_deg"):
        ViewsConfig(min_separation_deg=-1)
