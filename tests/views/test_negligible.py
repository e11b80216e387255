"""Views whose dynamic region is negligible are not queued (views.min_dynamic_fraction)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from anigs.cameras import save_cameras
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.render.labels import dynamic_masks
from anigs.stages.targets import queued_view_count
from anigs.views import ViewsConfig, plan_views

# cameras on a ring facing the centre: yaw 0 faces the ROI (centroid heading), and with a 60 deg
# FOV the +-90 views look along the ring, away from the blobs in the middle
SIDEWAYS = dict(layout="walk", min_coverage=0.0, min_content=0.0, width=64, height=48, num_locations=3, fov_deg=60.0,
                forward="centroid")
OLD_TOP_KEYS = ["views", "layout", "scene_coverage", "up_estimate", "coverage_after", "frustum_coverage_after",
                "roi_reachable_fraction", "locations", "roi_centroid", "up", "num_candidates", "convention"]
OLD_VIEW_KEYS = {"id", "location", "candidate", "yaw", "pitch", "heading_deg", "camera", "roi_visible",
                 "roi_visible_fraction", "visible", "coverage", "requested_yaw", "fov_deg", "replaced",
                 "overlap_prev", "overlap_prev_roi", "coverage_after", "frustum_coverage_after"}


@pytest.fixture(scope="module")
def plans(scene):
    gs, lab, cams = scene
    roi = lab == 4
    return {t: plan_views(gs, roi, cams, ViewsConfig(**SIDEWAYS, min_dynamic_fraction=t)) for t in (0.0, 0.005)}


def _fraction(gs, roi, cam) -> float:
    return float(dynamic_masks(gs, roi, [cam])[0].mean())


def test_sideways_views_are_dropped_and_the_rest_renumbered(scene, plans):
    gs, lab, _ = scene
    roi = lab == 4
    full, cut = plans[0.0], plans[0.005]
    assert len(full.views) == 9 and not full.dropped and full.dynamic_rule is None
    # independently of the planner: the fraction of the pixels the masks stage would mark
    truth = [_fraction(gs, roi, cam) for cam in full.cameras]
    assert [f >= 0.005 for f in truth] == [y == 0.0 for y in [0.0, 90.0, -90.0] * 3], truth
    assert [d["slot"] for d in cut.dropped] == [i for i, f in enumerate(truth) if f < 0.005]
    for d in cut.dropped:
        assert d["dynamic_fraction"] == pytest.approx(truth[d["slot"]], abs=1e-12)
        assert d["requested_yaw"] in (90.0, -90.0) and "negligible" in d["reason"]
        assert {**d["camera"], "name": ""} == {**full.views[d["slot"]]["camera"], "name": ""}
    kept = [i for i, f in enumerate(truth) if f >= 0.005]
    assert [v["id"] for v in cut.views] == [f"v{i:02d}" for i in range(len(kept))]
    assert [c.name for c in cut.cameras] == [v["id"] for v in cut.views]
    for v, i in zip(cut.views, kept):
        assert {**v["camera"], "name": ""} == {**full.views[i]["camera"], "name": ""}
        assert v["location"] == full.views[i]["location"] and v["yaw"] == full.views[i]["yaw"]
        assert v["dynamic_fraction"] == pytest.approx(truth[i], abs=1e-12)
    assert len(cut.coverage_after) == len(cut.views) and cut.views[1]["overlap_prev"] is not None
    data = cut.to_json()
    sec = data["dynamic_fraction"]
    assert sec["applied"] and sec["min"] == 0.005 and sec["kept_below_min"] is None
    assert sec["per_view"] == [v["dynamic_fraction"] for v in cut.views] and sec["dropped"] == cut.dropped
    json.dumps(data)  # serialisable


def test_dropped_views_drawn_on_the_topdown(scene, plans):
    from anigs.views.topdown import _DROPPED, draw_topdown

    gs, lab, _ = scene
    img = draw_topdown(plans[0.005], gs.means.numpy(), lab == 4, size=300)
    assert (np.abs(img.astype(int) - _DROPPED).sum(-1) == 0).sum() > 5
    img0 = draw_topdown(plans[0.0], gs.means.numpy(), lab == 4, size=300)
    assert (np.abs(img0.astype(int) - _DROPPED).sum(-1) == 0).sum() == 0


def _without_content(data: dict) -> dict:
    """views.json without the content test's section and per-view figures (present whatever the
    dynamic threshold: anigs.views.content)."""
    data.pop("content")
    for v in data["views"]:
        v.pop("content"), v.pop("edge_share"), v.pop("magnified")
    return data


def test_threshold_zero_is_the_old_queue(scene, plans, monkeypatch):
    """min_dynamic_fraction 0: nothing computed, the views.json content has exactly the old keys;
    a threshold every view passes gives the same queue plus the new section and per-view field."""
    import anigs.views.plan as plan_mod

    gs, lab, cams = scene
    old = _without_content(plans[0.0].to_json())
    assert list(old) == OLD_TOP_KEYS
    assert all(set(v) == OLD_VIEW_KEYS for v in old["views"])
    monkeypatch.setattr(plan_mod, "dynamic_fraction", lambda g, roi, cam: 0.5)
    every = _without_content(plan_views(gs, lab == 4, cams,
                                        ViewsConfig(**SIDEWAYS, min_dynamic_fraction=0.5)).to_json())
    sec = every.pop("dynamic_fraction")
    assert sec["dropped"] == [] and sec["per_view"] == [0.5] * 9
    for v in every["views"]:
        assert v.pop("dynamic_fraction") == 0.5
    assert json.dumps(every) == json.dumps(old)


def test_all_negligible_keeps_the_best_view(scene):
    gs, lab, cams = scene
    roi = lab == 4
    plan = plan_views(gs, roi, cams, ViewsConfig(**SIDEWAYS, min_dynamic_fraction=1.0))
    assert len(plan.views) == 1 and plan.views[0]["id"] == "v00" and len(plan.dropped) == 8
    best = plan.views[0]["dynamic_fraction"]
    assert 0 < best < 1.0 and all(d["dynamic_fraction"] <= best for d in plan.dropped)
    assert best == pytest.approx(_fraction(gs, roi, plan.cameras[0]), abs=1e-12)
    assert "kept the one with the largest" in plan.to_json()["dynamic_fraction"]["kept_below_min"]


def _cli(tmp_path, gs, cams, roi, params) -> dict:
    from anigs.cli import main

    gs.save_ply(tmp_path / "canonical.ply")
    save_cameras(tmp_path / "cameras.json", cams)
    eff = EffectsOutputs(tmp_path / "effects")
    eff.root.mkdir(exist_ok=True)
    np.save(eff.path("dynamic"), roi)
    out = ViewsOutputs(tmp_path / "views")
    assert main(["views", "--canonical", str(tmp_path / "canonical.ply"), "--cameras", str(tmp_path / "cameras.json"),
                 "--effects", str(eff.root), "--out", str(out.root),
                 "--params", json.dumps({**params, "topdown_size": 200})]) == 0
    assert queued_view_count(out.path("views")) == out.count() == len(out.report()["views"])
    return out.report()


def test_stage_drops_but_not_under_the_roi_fallback(tmp_path, scene):
    gs, lab, cams = scene
    data = _cli(tmp_path / "a", gs, cams[:4], lab == 4, {**SIDEWAYS, "num_locations": 2})
    assert len(data["views"]) == 2 and len(data["dynamic_fraction"]["dropped"]) == 4
    assert data["config"]["min_dynamic_fraction"] == 0.005
    # nothing to animate: the views look at the whole scene and none is dropped
    data = _cli(tmp_path / "b", gs, cams[:4], np.zeros(gs.num, bool),
                {**SIDEWAYS, "num_locations": 2, "min_dynamic_fraction": 1.0})
    assert data["roi_fallback"] and len(data["views"]) == 6
    sec = data["dynamic_fraction"]
    assert not sec["applied"] and "roi_fallback" in sec["not_applied"] and sec["dropped"] == []


def test_queued_view_count(tmp_path):
    p = tmp_path / "views.json"
    p.write_text(json.dumps({"views": [{"id": "v00"}, {"id": "v01"}], "dynamic_fraction": {"dropped": [{}]}}))
    assert queued_view_count(p) == 2
    for bad in ([{"id": "v00"}, {"id": "v02"}], []):
        p.write_text(json.dumps({"views": bad}))
        with pytest.raises(ValueError, match="v00"):
            queued_view_count(p)
    # the workflow imports it without torch
    code = "import sys; from anigs.stages.targets import queued_view_count; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_config_range():
    with pytest.raises(ValueError, match="min_dynamic_fraction"):
        ViewsConfig(min_dynamic_fraction=1.5)
