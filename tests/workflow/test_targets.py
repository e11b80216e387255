"""The named targets: an ``all_<stage>`` rule for every stage of the registry, planning that
stage's jobs and only what they need (dry runs of the tiny config, config/test.yaml)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from anigs.registry import STAGES

ROOT = Path(__file__).resolve().parents[2]


def _snakemake(tmp_path: Path, flag: str, *targets: str, config: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    """``snakemake FLAG`` (``-n``, ``--list-rules``) on the tiny config, results under ``tmp_path``."""
    exe = Path(sys.executable).with_name("snakemake")
    cmd = [str(exe), flag, "--cores", "1", "--configfile", "config/test.yaml", "--config",
           f"results={tmp_path / 'results'}", *config, "--", *targets]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)


def _planned(stdout: str) -> dict[str, int]:
    """rule -> job count of a dry run's first "Job stats" table."""
    table = stdout.split("Job stats:", 1)[1].split("total", 1)[0]
    return {m[1]: int(m[2]) for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", table, re.M)}


def test_every_stage_has_an_all_target(tmp_path):
    res = _snakemake(tmp_path, "--list-rules")
    assert res.returncode == 0, res.stderr[-3000:]
    targets = {r for r in res.stdout.split() if r.startswith("all_")}
    assert targets == {f"all_{s.name}" for s in STAGES}


def test_all_effects_plans_the_effects_job_and_its_upstream_only(tmp_path):
    res = _snakemake(tmp_path, "-n", "all_effects")
    assert res.returncode == 0, res.stderr[-3000:]
    assert _planned(res.stdout) == {"capture_synthetic": 1, "sfm": 1, "static": 1, "effects": 1, "all_effects": 1}
    assert f"{tmp_path}/results/tiny/effects/overview.png" in res.stdout
    assert not (tmp_path / "results").exists(), "a dry run writes nothing"


def test_all_round_without_round_jobs_names_the_setting(tmp_path):
    res = _snakemake(tmp_path, "-n", "all_round", config=("round_jobs=view",))
    assert res.returncode != 0
    assert "round_jobs: round" in res.stdout + res.stderr, (res.stdout + res.stderr)[-3000:]
