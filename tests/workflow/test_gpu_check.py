"""benchmarks/gpu_check.sh without a GPU: the CUDA parts reported as skipped, exit 0; and its
measured parts (benchmarks/gpu_check_parts.py) and table run on the CPU at small sizes."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[2]
CUDA_PARTS = ["gsplat", "static", "agree", "static_cpu", "ltx", "update", "demo", "gpu_tests"]
sys.path.insert(0, str(ROOT / "benchmarks"))


def _rows(table: str) -> dict[str, list[str]]:
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0] not in ("part", "---"):
            rows[cells[0]] = cells[1:]
    return rows


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a GPU: the skipped path cannot be shown")
def test_without_cuda_every_cuda_part_is_skipped(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    env = {**os.environ, "PYTHON": sys.executable, "ANIGS_GPU_CHECK_WORK": str(tmp_path / "work"),
           "ANIGS_GPU_CHECK_WHEELS": str(tmp_path / "no-wheels"), "OUT": str(out)}
    env.pop("ANIGS_GPU_CHECK_DEVICE", None)
    res = subprocess.run(["bash", "benchmarks/gpu_check.sh"], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    rows = _rows(res.stdout)
    assert rows["install"][0] == "SKIPPED" and "no wheels" in rows["install"][2]
    assert rows["env"][0] == "OK", rows["env"]
    for part in CUDA_PARTS:
        assert rows[part][0] == "SKIPPED", (part, rows[part])
        assert "no CUDA device" in rows[part][2], (part, rows[part])
    assert (out / "table.md").read_text() == (tmp_path / "work" / "table.md").read_text()
    env_json = json.loads((out / "results.json").read_text())["env"]
    assert env_json["cuda_available"] is False and env_json["torch"] == torch.__version__


def test_parts_and_table_on_the_cpu(tmp_path):
    """The measured parts at small sizes on the CPU (gsplat's place taken by the torch backend), then
    the table from their JSON: the code that runs only on the GPU machine otherwise."""
    import gpu_check_parts as parts
    import gpu_check_table

    work = tmp_path / "work"
    res, cap = work / "res", work / "capture"
    run = lambda *a: parts.main([str(x) for x in a])  # noqa: E731
    assert run("capture", res / "capture.json", "--dir", cap, "--small") == 0
    assert run("static", res / "static.json", "--dir", cap, "--device", "cpu", "--backend", "cpu",
               "--iterations", 20, "--eval-every", 10, "--ply", work / "fitted.ply") == 0
    assert run("agree", res / "agree.json", "--dir", cap, "--ply", work / "fitted.ply", "--device", "cpu",
               "--views", 2) == 0
    assert run("update", res / "update.json", "--device", "cpu", "--steps", 2, "--small") == 0
    agree = json.loads((res / "agree.json").read_text())
    # the torch backend against the CPU kernel: the same renderer, so far inside the tolerance
    assert agree["backend"] == "torch" and agree["pass"] and agree["min_psnr"] > 60
    assert agree["model"] == str(work / "fitted.ply")
    static = json.loads((res / "static.json").read_text())
    assert [r["iteration"] for r in static["curve"]] == [0, 10, 20] and static["test_psnr"] > 10
    upd = json.loads((res / "update.json").read_text())
    assert upd["steps"] == 2 and upd["finite"]
    (res / "gsplat.json").write_text(json.dumps({"seconds": 123.4, "built_before": False, "arch": "9.0", "max_jobs": "16"}))
    (work / "status.tsv").write_text("gsplat\tOK\t130.0\t\nstatic\tOK\t1.0\t\nagree\tOK\t1.0\t\nupdate\tOK\t1.0\t\n"
                                     "ltx\tFAILED\t2.0\texit 1: boom\ndemo\tSKIPPED\t0\tno time left\n")
    rows = _rows(gpu_check_table.table(work))
    assert rows["gsplat"] == ["OK", "130.0", "compiled in 123.4 s (TORCH_CUDA_ARCH_LIST=9.0, MAX_JOBS=16)"]
    assert rows["agree"][0] == "OK" and rows["agree"][2].startswith("PASS: torch vs CPU kernel on the fitted model")
    assert "held-out PSNR" in rows["static"][2] and "steps/s" in rows["update"][2]
    assert rows["ltx"] == ["FAILED", "2.0", "exit 1: boom"] and rows["demo"] == ["SKIPPED", "0", "no time left"]
