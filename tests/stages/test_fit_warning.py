"""The static fit's too-blurry warning, read once (``StaticOutputs.fit_warning``), and the effects stage reading it
from the static folder it declares (``--static``), not from beside ``--canonical``."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
from anigs.effects.config import EffectsConfig
from anigs.stages import effects
from anigs.stages.static import Outputs as StaticOutputs
from tests.masks.test_lift import toy_scene


def test_fit_warning_reads_the_accuracy_record(tmp_path):
    static = StaticOutputs(tmp_path / "static")
    assert static.fit_warning() is None  # no metrics
    static.root.mkdir()
    static.path("metrics").write_text(json.dumps({"num_gaussians": 3}))  # an imported splat's: no accuracy record
    assert static.fit_warning() is None
    static.path("metrics").write_text(json.dumps({"accuracy": {"warning": None}}))
    assert static.fit_warning() is None
    static.path("metrics").write_text(json.dumps({"accuracy": {"warning": "the static fit is too blurry"}}))
    assert static.fit_warning() == "the static fit is too blurry"


def test_the_effects_stage_takes_the_warning_from_its_declared_static_folder(tmp_path, monkeypatch):
    g, _, _ = toy_scene(ring=4)
    static = StaticOutputs(tmp_path / "static")
    static.root.mkdir()
    g.save_ply(static.path("canonical"))
    static.path("metrics").write_text(json.dumps({"accuracy": {"warning": "the static fit is too blurry"}}))
    cam = Camera(intrinsics_from_fov(60, 48, 36), look_at((0.0, -4.5, 1.5), (0.0, 0.0, 0.8)), 48, 36, "v00")
    save_cameras(tmp_path / "cameras.json", [cam])
    seen = []
    decision = lambda *a: SimpleNamespace(result=SimpleNamespace(region_of=np.zeros(g.num)),  # noqa: E731
                                          dynamic=np.zeros(g.num, bool), report={"chosen": []})
    monkeypatch.setattr(effects, "analysed_photos", lambda images, cams, cfg: ([np.zeros((36, 48, 3))], cams))
    monkeypatch.setattr(effects, "decide_effects", decision)
    monkeypatch.setattr(effects, "save_overview", lambda path, result, warnings=(): seen.append(list(warnings)))
    for name, folder in (("declared", static), ("omitted", None)):
        out = effects.run(effects.Inputs(canonical=static.path("canonical"), cameras=tmp_path / "cameras.json",
                                         images=tmp_path / "images", out=effects.Outputs(tmp_path / name),
                                         static=folder), EffectsConfig())
        seen.append(out.report().get("static_fit_warning"))
    # beside --canonical lies a warning, but only the declared folder is read
    assert seen == [["the static fit is too blurry"], "the static fit is too blurry", [], None]
    assert "--static" in effects.Inputs(canonical="c.ply", cameras="c.json", images="i", out="o",
                                        static=static).argv()
