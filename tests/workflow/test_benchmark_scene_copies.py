"""benchmarks/real_captures.py --static: the benchmark's scene files copied with static-section
overrides (dotted keys nest), which the workflow reads as each scene's fit config."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from real_captures import SCENES, parse_kv, scene_copies  # noqa: E402


def test_static_overrides_reach_the_fit_command(tmp_path):
    folder = scene_copies(tmp_path / "scenes", parse_kv(["holdout_every=0", "densify.max_gaussians=1234"]))
    names = sorted(p.name for p in SCENES.glob("*.yaml"))
    assert sorted(p.name for p in folder.glob("*.yaml")) == names
    castle = yaml.safe_load((folder / "sceaux-castle.yaml").read_text())
    original = yaml.safe_load((SCENES / "sceaux-castle.yaml").read_text())
    assert castle["static"] == {**original.get("static", {}), "holdout_every": 0, "densify": {"max_gaussians": 1234}}
    assert {k: v for k, v in castle.items() if k != "static"} == {k: v for k, v in original.items() if k != "static"}
    photos = tmp_path / "photos" / "sceaux-castle"
    photos.mkdir(parents=True)
    (photos / "a.jpg").write_bytes(b"")  # the scene check wants a photo; the dry run reads none
    exe = Path(sys.executable).with_name("snakemake")
    target = tmp_path / "results" / "sceaux-castle" / "static" / "canonical.ply"
    res = subprocess.run([str(exe), "-n", "-p", "--cores", "1", "--config", 'scenes=["sceaux-castle"]',
                          f"results={tmp_path / 'results'}", f"scene_dir={folder}", "--", str(target)],
                         cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "ANIGS_CAPTURES": str(tmp_path / "photos")})
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    static_cmd = next(line for line in res.stdout.splitlines() if " static --images" in line)
    assert '"holdout_every": 0' in static_cmd and '"max_gaussians": 1234' in static_cmd, static_cmd
