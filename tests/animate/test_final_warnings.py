"""The final stage says beside the videos what the static fit and the view queue warned about."""
from __future__ import annotations

import json

import numpy as np

from anigs.animate.config import FinalConfig
from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.stages import final
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from tests.masks.test_lift import toy_scene


def _static_scene(tmp_path, warning: str | None, advice: str | None):
    g, _, _ = toy_scene(ring=4)
    static, views = StaticOutputs(tmp_path / "static"), ViewsOutputs(tmp_path / "views")
    static.root.mkdir(), views.root.mkdir()
    g.save_ply(static.path("canonical"))
    static.path("metrics").write_text(json.dumps({"accuracy": {"warning": warning}}))
    cam = Camera(intrinsics_from_fov(60, 48, 36), look_at((0.0, -4.5, 1.5), (0.0, 0.0, 0.8)), 48, 36, "v00")
    views.path("views").write_text(json.dumps({"views": [{"id": "v00", "camera": cam.to_dict()}],
                                               "motion": None if advice is None else {"advice": advice}}))
    return static, views


def test_final_json_carries_the_fit_warning_and_the_views_advice(tmp_path):
    static, views = _static_scene(tmp_path, "the static fit is too blurry", "no view shows the moving region")
    out = final.run(final.Inputs(static=static, views=views, out=tmp_path / "final"), FinalConfig(frames=2))
    summary = json.loads(out.path("summary").read_text())
    assert summary["warnings"] == ["the static fit is too blurry", "no view shows the moving region"]
    assert np.allclose(summary["background"], [0.5, 0.5, 0.5])


def test_final_json_has_no_warnings_when_nothing_was_said(tmp_path):
    static, views = _static_scene(tmp_path, None, None)
    out = final.run(final.Inputs(static=static, views=views, out=tmp_path / "final"), FinalConfig(frames=2))
    assert "warnings" not in json.loads(out.path("summary").read_text())
