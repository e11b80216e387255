"""Local model weights are inputs of the jobs that load them (anigs.weight_inputs): a weight file updated
at the same path re-runs the job, through a real Snakemake dry-run on the workflow."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from anigs.weight_inputs import effects_weights, eval_weights, masks_weights, refine_weights, weight_files

ROOT = Path(__file__).resolve().parents[2]


def test_weight_files_of_a_file_a_folder_and_of_nothing(tmp_path):
    folder = tmp_path / "seg"
    (folder / "sub").mkdir(parents=True)
    (folder / ".cache").mkdir()
    for f in ("config.json", "model.safetensors", "sub/vae.safetensors", ".cache/lock", ".hidden"):
        (folder / f).write_text("x")
    ckpt = tmp_path / "sam2.pt"
    ckpt.write_text("x")
    assert weight_files(folder) == [str(folder / "config.json"), str(folder / "model.safetensors"),
                                    str(folder / "sub" / "vae.safetensors")]
    assert weight_files(ckpt, None, "", "auto", tmp_path / "missing") == [str(ckpt)]
    assert effects_weights({"segmenter": {"backend": "none", "weights": str(folder)}}) == []
    assert effects_weights({"segmenter": {"backend": "segformer", "weights": str(folder)}})[0].endswith("config.json")
    assert masks_weights({"backend": "effects", "sam2": {"checkpoint": str(ckpt)}}) == []
    assert masks_weights({"backend": "sam2", "sam2": {"checkpoint": str(ckpt)}}) == [str(ckpt)]
    assert refine_weights({"prior": "procedural", "ltx": {"model_path": str(folder)}}) == []
    assert len(refine_weights({"prior": "ltx", "ltx": {"model_path": str(folder), "prompt_embeds": str(ckpt)}})) == 4
    assert eval_weights({"i3d_path": "auto"}) == [] and eval_weights({"i3d_path": str(ckpt)}) == [str(ckpt)]


def _touch(path: Path, when: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists():
        path.write_text("x")
    os.utime(path, (when, when))


def test_an_updated_segmenter_weight_file_reruns_the_effects_job(tmp_path):
    """The effects job of a photo scene whose segmenter has local weights: nothing to do while its
    outputs are newer than the weight files; after one weight file changes, the job runs again."""
    photos, scenes, seg, results = (tmp_path / n for n in ("photos", "scenes", "seg", "results"))
    for d in (photos, scenes):
        d.mkdir()
    (photos / "p0.png").write_bytes(b"")  # the scene check wants a photo; no job reads it here
    (scenes / "ph.yaml").write_text(f"source: photos\nphotos: {photos}\neffects: auto\nprompt: a bush\n")
    (tmp_path / "cfg.yaml").write_text(f"effects:\n  segmenter:\n    backend: segformer\n    weights: {seg}\n")
    old, mid = time.time() - 200, time.time() - 100
    for f in ("config.json", "model.safetensors"):
        _touch(seg / f, old)
    scene = results / "ph"
    for f in ("static/canonical.ply", "sfm/cameras.json", "sfm/images/p0.png"):
        _touch(scene / f, old)
    os.utime(scene / "sfm" / "images", (old, old))
    for f in ("effects.json", "regions.npy", "dynamic.npy", "overview.png"):
        _touch(scene / "effects" / f, mid)
    exe = Path(sys.executable).with_name("snakemake")
    if not exe.exists():
        pytest.skip("snakemake is not installed beside this Python")

    def dry_run() -> str:
        res = subprocess.run([str(exe), "-n", "--cores", "1", "--rerun-triggers", "mtime", "--allowed-rules", "effects",
                              "--configfile", str(tmp_path / "cfg.yaml"), "--config", f"scene_dir={scenes}", "scenes=[ph]",
                              f"results={results}", "--", str(scene / "effects" / "effects.json")],
                             cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
        return res.stdout + res.stderr

    assert "Nothing to be done" in dry_run()
    _touch(seg / "model.safetensors", time.time())
    out = dry_run()
    assert "checkpoint effects:" in out and "Updated input files" in out and "model.safetensors" in out, out[-3000:]
