"""Per-rule breakdown of a run's Snakemake benchmark TSVs (anigs.reports.tradeoff, benchmarks/rules.py)."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from anigs.reports.benchmark_tsv import (benchmark_files, breakdown_total, compare_breakdowns, read_benchmark, rule_breakdown,
                                  rule_name)

HEAD = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _tsv(path: Path, *runs: tuple[float, float | str, float]) -> Path:
    """A Snakemake benchmark TSV: one line per repeat of (wall s, max_rss MB, cpu_time)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEAD + "".join(f"{s}\t0:00:01\t{rss}\t1\t1\t1\t0\t0\t50\t{cpu}\n" for s, rss, cpu in runs))
    return path


def _run(root: Path, scale: float = 1.0) -> Path:
    res = root / "results"
    _tsv(res / "demo" / "benchmarks" / "static.tsv", (90 * scale, 500, 60 * scale))
    for r in (1, 2):
        for v in ("v00", "v01", "v12"):
            _tsv(res / "demo" / "full" / "benchmarks" / f"round{r}" / f"render_clip_{v}.tsv", (10 * scale, 300, 2))
        _tsv(res / "demo" / "full" / "benchmarks" / f"round{r}" / "update.tsv", (50 * scale, 800, 40 * scale))
        _tsv(res / "demo" / "full" / "benchmarks" / f"round{r}" / "round.tsv", (1.0, 200, 1.0))
    _tsv(res / "demo" / "full" / "benchmarks" / "final.tsv", (5.0, "NA", 4.0))
    (res / "demo" / "full" / "eval").mkdir(parents=True)
    (res / "demo" / "full" / "eval" / "table.tsv").write_text("a\tb\n1\t2\n")  # not a benchmark
    return res


def test_rule_names_drop_the_view_suffix():
    assert rule_name("r/demo/full/benchmarks/round2/render_clip_v03.tsv") == "render_clip"
    assert rule_name("round1/refine_v112.tsv") == "refine"
    assert rule_name("round1/update.tsv") == "update"
    assert rule_name("round3/round.tsv") == "round"
    assert rule_name("benchmarks/final_render.tsv") == "final_render"
    assert rule_name("benchmarks/static.tsv") == "static"
    assert rule_name("benchmarks/x_vfoo.tsv") == "x_vfoo"


def test_breakdown_sums_jobs_per_rule_sorted_by_wall(tmp_path):
    res = _run(tmp_path)
    files = benchmark_files(res)
    assert len(files) == 1 + 2 * 5 + 1 and all("benchmarks" in f.parts for f in files)
    rows = rule_breakdown(files)
    assert [r["rule"] for r in rows] == ["update", "static", "render_clip", "final", "round"]
    by = {r["rule"]: r for r in rows}
    assert by["render_clip"] == {"rule": "render_clip", "jobs": 6, "seconds": 60.0, "cpu_seconds": 12.0,
                                 "max_rss_mb": 300.0}
    assert by["update"]["max_rss_mb"] == 800.0 and by["update"]["cpu_seconds"] == 80.0
    assert by["final"]["max_rss_mb"] is None  # NA in the file
    total = breakdown_total(rows)
    assert total == {"rule": "total", "jobs": 12, "seconds": 257.0, "cpu_seconds": 158.0, "max_rss_mb": 800.0}
    # a sub-folder of the tree, and a benchmarks folder itself
    assert {r["rule"] for r in rule_breakdown(benchmark_files(res / "demo" / "full"))} == {
        "update", "render_clip", "final", "round"}
    assert len(benchmark_files(res / "demo" / "full" / "benchmarks" / "round1")) == 5


def test_repeats_average_wall_and_take_the_largest_memory(tmp_path):
    p = _tsv(tmp_path / "benchmarks" / "update.tsv", (2.0, 100, 1.0), (4.0, 300, 3.0))
    assert read_benchmark(p)[1]["max_rss"] == 300.0
    (row,) = rule_breakdown([p])
    assert (row["seconds"], row["cpu_seconds"], row["max_rss_mb"]) == (3.0, 2.0, 300.0)


def test_older_snakemake_without_cpu_time_and_non_benchmarks(tmp_path):
    old = tmp_path / "benchmarks" / "static.tsv"
    old.parent.mkdir()
    old.write_text("s\th:m:s\tmax_rss\n7.5\t0:00:07\t10\n")
    new = _tsv(tmp_path / "benchmarks" / "static_v01.tsv", (2.5, 20, 1.0))
    (row,) = rule_breakdown([old, new])
    assert row["jobs"] == 2 and row["seconds"] == 10.0 and row["cpu_seconds"] is None and row["max_rss_mb"] == 20
    assert breakdown_total([row])["cpu_seconds"] is None
    bad = tmp_path / "benchmarks" / "bad.tsv"
    bad.write_text("a\tb\n1\t2\n")
    with pytest.raises(ValueError, match="bad.tsv"):
        rule_breakdown([bad])


def test_compare_before_after(tmp_path):
    before = rule_breakdown(benchmark_files(_run(tmp_path / "b", scale=2.0)))
    after = [r for r in rule_breakdown(benchmark_files(_run(tmp_path / "a"))) if r["rule"] != "round"]
    cmp = {r["rule"]: r for r in compare_breakdowns(before, after)}
    assert cmp["update"]["seconds_before"] == 200.0 and cmp["update"]["seconds_after"] == 100.0
    assert cmp["update"]["seconds_ratio"] == 0.5 and cmp["update"]["cpu_seconds_ratio"] == 0.5
    assert cmp["round"]["jobs_after"] is None and cmp["round"]["seconds_ratio"] is None  # only before
    assert list(cmp)[-1] == "round"


def _script():
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "rules.py"
    spec = importlib.util.spec_from_file_location("benchmarks_rules", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_script_prints_the_table_compare_and_json(tmp_path, capsys):
    after, before = _run(tmp_path / "a"), _run(tmp_path / "b", scale=2.0)
    out_json = tmp_path / "out" / "rules.json"
    assert _script().main([str(after), "--compare", str(before), "--json", str(out_json)]) == 0
    text = capsys.readouterr().out
    print(text)
    lines = text.splitlines()
    assert lines[1].split() == ["rule", "jobs", "wall", "s", "wall", "%", "CPU", "s", "peak", "RSS", "MB"]
    assert lines[3].split()[:3] == ["update", "2", "100.0"]
    assert any(ln.split()[:3] == ["total", "12", "257.0"] for ln in lines)
    assert "after/before" in text and any(ln.split()[:2] == ["update", "2/2"] and ln.split()[4] == "0.50"
                                          for ln in lines)
    data = json.loads(out_json.read_text())
    assert data["total"]["seconds"] == 257.0 and data["before_total"]["seconds"] > 257.0
    assert data["compare"][-1]["rule"] == "total"
    with pytest.raises(SystemExit, match="no benchmark TSVs"):
        _script().main([str(tmp_path / "empty")])
