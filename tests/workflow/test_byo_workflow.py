"""Bring your own reconstruction, end to end through real Snakemake jobs (config/test.yaml): a COLMAP project
(the tiny scene's sfm folder, as a user's project) and a splat trained on it (the tiny scene's own fit, laid
out as an INRIA 3DGS run without its cameras.json) give an animated scene with no capture, SfM or fit job."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from anigs.stages.static import Outputs as StaticOutputs

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow
BG = [0.62, 0.76, 0.92]  # the tiny scene's sky (config/scenes/tiny.yaml)


def _snakemake(results: Path, *args: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("snakemake")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}")
    cmd = [str(exe), "--cores", "2", "--configfile", "config/test.yaml", "--workflow-profile",
           "workflow/profiles/default", *args]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1500, env=env)
    if res.returncode != 0:
        logs = "\n".join(f"--- {p}\n{p.read_text()[-3000:]}" for p in results.rglob("*.log"))
        pytest.fail(f"snakemake failed:\n{res.stdout[-3000:]}\n{res.stderr[-5000:]}\n{logs[-10000:]}")
    return res


def _jobs(res: subprocess.CompletedProcess) -> set[str]:
    return {line.split("rule ", 1)[1].rstrip(":") for line in (res.stdout + res.stderr).splitlines()
            if line.startswith(("rule ", "localrule "))}


def test_a_colmap_project_and_its_splat_animate_without_sfm_or_fit(tmp_path):
    first = tmp_path / "first"
    _snakemake(first, "all_static", "--config", f"results={first}")
    tiny = first / "tiny"
    run = tmp_path / "user_run" / "point_cloud" / "iteration_300"
    run.mkdir(parents=True)
    shutil.copy(tiny / "static" / "canonical.ply", run / "point_cloud.ply")
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "proj.yaml").write_text(
        f"source: colmap\nimages: {tiny / 'sfm' / 'images'}\nsparse: {tiny / 'sfm' / 'sparse'}\n"
        f"splat: {run / 'point_cloud.ply'}\nbackground: {BG}\n"
        "effects: [foliage_sway, leaf_flutter, grass_wave, flower_bob]\n"
        "prompt: a garden with trees, bushes, grass and flowers swaying gently in the wind\n")
    results = tmp_path / "results"
    res = _snakemake(results, "--config", f"results={results}", f"scene_dir={scenes}", "scenes=[proj]")
    ran = _jobs(res)
    assert "colmap_import" in ran and "static" in ran and {"final", "export", "view"} <= ran, ran
    assert not ran & {"capture_synthetic", "capture_photos", "sfm"}, ran
    scene = results / "proj"
    imported = StaticOutputs(scene / "static").metrics()
    assert imported["iterations"] == 0 and imported["imported"]["frame"] == "colmap", imported["imported"]
    fitted = StaticOutputs(tiny / "static").metrics()
    # the same splat on the same photos and split renders the same held-out figure (frame recovered)
    assert imported["test_psnr"] == pytest.approx(fitted["test_psnr"], abs=0.1)
    assert imported["num_gaussians"] == fitted["num_gaussians"]
    effects = json.loads((scene / "effects" / "effects.json").read_text())
    assert effects["chosen"], effects.get("reasons")
    assert (scene / "full" / "export" / "animated.ply").is_file() and (scene / "full" / "viewer" / "index.html").is_file()
    report = json.loads((scene / "sfm" / "report.json").read_text())
    assert report["registered"] == report["images"] and report["mapping"]["model_format"] == "binary"
