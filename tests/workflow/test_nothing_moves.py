"""A scene with nothing to animate (the bare courtyard) runs end to end with no round at all:
the effects stage finds no effect, one job writes a still model, and the final videos are the
static scene bit for bit (config/scenes/tiny_courtyard.yaml, through real Snakemake jobs)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def test_bare_courtyard_runs_no_round(tmp_path):
    from anigs.animate.deform import load_model
    from anigs.stages.effects import Outputs as EffectsOutputs
    from anigs.video import load_clip

    results = tmp_path / "results"
    exe = Path(sys.executable).with_name("snakemake")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
    res = subprocess.run([str(exe), "--cores", "2", "--configfile", "config/test.yaml", "--config",
                          f"results={results}", "scenes=[tiny_courtyard]", "--workflow-profile",
                          "workflow/profiles/default"], cwd=ROOT, capture_output=True, text=True, timeout=1500, env=env)
    if res.returncode != 0:
        logs = "\n".join(f"--- {p}\n{p.read_text()[-3000:]}" for p in results.rglob("*.log"))
        pytest.fail(f"snakemake failed:\n{res.stderr[-6000:]}\n{logs[-12000:]}")
    scene = results / "tiny_courtyard"
    effects = EffectsOutputs(scene / "effects").report()
    assert effects["chosen"] == [] and effects["detected"] == []
    variant = scene / "full"
    ran = {line.split("rule ", 1)[1].rstrip(":") for line in res.stdout.splitlines() + res.stderr.splitlines()
           if line.startswith("rule ") or line.startswith("localrule ")}
    assert not ran & {"round", "render_clip", "refine", "update"}, ran
    assert "still" in ran
    assert not list(variant.glob("round*"))
    _, deformation, payload = load_model(variant / "still" / "model.pt")
    assert deformation.num_dynamic == 0 and payload["extra"]["still"]
    final = json.loads((variant / "final" / "final.json").read_text())
    assert "no effect" in final["nothing_moves"]
    for clip_path in sorted((variant / "final" / "clips").glob("*.npz")):
        clip, _ = load_clip(clip_path)
        assert np.array_equal(clip, np.broadcast_to(clip[:1], clip.shape)), clip_path  # bit for bit still
    metrics = json.loads((variant / "eval" / "metrics.json").read_text())
    assert metrics  # the evaluation ran on the still scene
    assert (variant / "export" / "scene.anigs").is_file() and (variant / "viewer" / "index.html").is_file()
