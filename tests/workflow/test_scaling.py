"""benchmarks/scaling.py's machinery at tiny sizes: the per-process measurement, the exponent fit,
the report, and a --smoke run (three tiny synthetic captures) that resumes without re-running."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import scaling  # noqa: E402


def test_exponent_is_the_log_log_slope():
    assert scaling.fit_exponent([1, 2, 4, 8], [3, 12, 48, 192]) == pytest.approx(2.0)
    assert scaling.fit_exponent([10, 100, 1000], [5, 5, 5]) == pytest.approx(0.0, abs=1e-12)
    assert math.isnan(scaling.fit_exponent([4, 4], [1, 2]))  # one distinct x: no slope


def _measure_in_small_process(code: str, log: Path) -> dict:
    """scaling.measure from a fresh process without torch (as the benchmark runs it: Linux counts the
    launcher's memory at the fork into the child's peak, and this test process holds torch)."""
    runner = ("import json, sys; sys.path.insert(0, sys.argv[1]); import scaling; "
              "print(json.dumps(scaling.measure([sys.executable, '-c', sys.argv[2]], scaling.Path(sys.argv[3]))))")
    out = subprocess.run([sys.executable, "-c", runner, str(ROOT / "benchmarks"), code, str(log)],
                         capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    return json.loads(out.stdout)


def test_measure_sees_the_child_s_memory_and_cpu(tmp_path):
    code = "import time; b = bytearray(300 * 2**20); b[::4096] = b'x' * len(b[::4096]); t = time.process_time()\n" \
           "while time.process_time() - t < 0.3: pass"
    r = _measure_in_small_process(code, tmp_path / "a.log")
    assert r["rss_mib"] > 290 and r["cpu_s"] >= 0.3 and r["wall_s"] >= r["cpu_s"] * 0.5
    small = _measure_in_small_process("pass", tmp_path / "b.log")
    assert small["rss_mib"] < r["rss_mib"] - 200
    with pytest.raises(RuntimeError, match="boom"):
        scaling.measure([sys.executable, "-c", "raise SystemExit('boom')"], tmp_path / "c.log")


def test_report_names_the_worst_growing_stage():
    rows = [{"axis": "frames", "value": v, "stages": {
        "render_clip": {"cpu_s": v * 0.1, "wall_s": v * 0.2, "rss_mib": 300, "load": 1.0},
        "update": {"cpu_s": (v / 25) ** 2 * 10, "wall_s": 1, "rss_mib": 300 + v, "load": 1.0}}} for v in (25, 49, 121)]
    text = scaling.report(rows)
    assert "| frames | render_clip | 1.00 | 1.00 | 0.00 | 3 |" in text
    assert "| frames | update | 2.00 | 2.00 |" in text
    assert "Worst-growing: update along frames (CPU exponent 2.00)" in text


def test_smoke_run_measures_three_points_and_resumes(tmp_path):
    assert scaling.main(["--smoke", "--out", str(tmp_path)]) == 0
    rows = [json.loads(x) for x in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [(r["axis"], r["value"]) for r in rows] == [("photos", 6), ("photos", 8), ("photos", 12)]
    for r in rows:
        f = r["stages"]["capture"]
        assert f["cpu_s"] > 0 and f["rss_mib"] > 50 and f["wall_s"] > 0
    assert len(list((tmp_path / "work" / "photos-12" / "capture").glob("gt/cameras.json"))) == 1
    md = (tmp_path / "scaling.md").read_text()
    assert "| photos | capture |" in md and "Worst-growing: capture along photos" in md
    assert scaling.main(["--smoke", "--out", str(tmp_path)]) == 0  # nothing left to run
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 3
