"""Accuracy-versus-time sweep: its variants, seconds from benchmark TSVs, the CSV and plots."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import pytest

from anigs.reports.tradeoff import (SweepPoint, benchmark_seconds, front_section, mark_fronts, markdown_report,
                            metric_directions, pareto_front, plot_knob, report_fronts, report_rows, stage_owner,
                            sweep_points, variant_name, write_csv)

OVERRIDES = {"full": {}, "no_composed_v2v": {"refine": {"compose": False}}}


def test_sweep_points_merge_the_knob_over_the_base_variant():
    pts = sweep_points({"update.steps": [40, 120], "refine.procedural.amplitude_scale": [0.5]}, "no_composed_v2v",
                       OVERRIDES)
    assert [p.variant for p in pts] == ["tradeoff-update-steps-40", "tradeoff-update-steps-120",
                                        "tradeoff-refine-procedural-amplitude_scale-0p5"]
    assert pts[0].overrides == {"refine": {"compose": False}, "update": {"steps": 40}}
    assert pts[2].overrides == {"refine": {"compose": False, "procedural": {"amplitude_scale": 0.5}}}
    assert OVERRIDES["no_composed_v2v"] == {"refine": {"compose": False}}  # base left untouched


def test_value_equal_to_the_base_setting_reuses_the_base_variant():
    pts = sweep_points({"update.steps": [40, 120]}, "full", OVERRIDES, base_value=lambda knob: 120)
    assert [p.variant for p in pts] == ["tradeoff-update-steps-40", "full"]


def test_null_drops_a_knob():
    assert sweep_points({"update.steps": None}, "full", OVERRIDES) == []


@pytest.mark.parametrize("knobs,match", [
    ({"sfm.max_features": [500]}, "sfm.max_features"),  # SfM is shared by the whole sweep
    ({"nonsense.key": [1]}, "nonsense.key"),
    ({"update": [1]}, "update"),  # a bare section takes mappings
    ({"views": [{}]}, "views"),
    ({"update.steps": []}, "update.steps"),
])
def test_bad_knobs_are_named(knobs, match):
    with pytest.raises(ValueError, match=match):
        sweep_points(knobs, "full", OVERRIDES)


def test_unknown_base_is_named():
    with pytest.raises(ValueError, match="nope"):
        sweep_points({"update.steps": [1]}, "nope", OVERRIDES)


BASE = {"static.iterations": 1000, "views.width": 256, "views.height": 192, "update.steps": 120}


def test_per_scene_knobs_become_derived_scenes_of_the_base_variant():
    pts = sweep_points({"static.iterations": [500, 1000], "views": [{"width": 128, "height": 96}]}, "no_composed_v2v",
                       OVERRIDES, base_value=BASE.get)
    assert [(p.scene("demo"), p.variant) for p in pts] == [
        ("demo--tradeoff-static-iterations-500", "no_composed_v2v"), ("demo", "no_composed_v2v"),
        ("demo--tradeoff-views-height-96-width-128", "no_composed_v2v")]
    assert pts[0].scene_overrides == {"static": {"iterations": 500}}
    assert pts[0].overrides == {"refine": {"compose": False}}  # the base variant's own overrides
    assert pts[2].scene_overrides == {"views": {"width": 128, "height": 96}}


def test_a_mapping_equal_to_the_base_settings_reuses_the_base():
    pts = sweep_points({"views": [{"width": 256, "height": 192}, {"width": 256, "height": 96}]}, "full", OVERRIDES,
                       base_value=BASE.get)
    assert [p.scene("demo") for p in pts] == ["demo", "demo--tradeoff-views-height-96-width-256"]


def test_a_mapping_value_of_a_variant_section_sets_several_keys():
    pts = sweep_points({"update": [{"steps": 40, "num_bases": 6}]}, "full", OVERRIDES, base_value=BASE.get)
    assert pts[0].variant == "tradeoff-update-num_bases-6-steps-40"
    assert pts[0].overrides == {"update": {"steps": 40, "num_bases": 6}} and not pts[0].scene_tag


def test_derived_scenes_reuse_the_stages_upstream_of_their_knob():
    st, vw = "demo--tradeoff-static-iterations-500", "demo--tradeoff-views-height-96-width-128"
    assert [stage_owner(st, s) for s in ("capture", "sfm", "static", "views", "masks")] == [
        "demo", "demo", st, st, st]
    assert [stage_owner(vw, s) for s in ("capture", "sfm", "static", "views", "masks")] == [
        "demo", "demo", "demo", vw, vw]
    assert stage_owner("demo", "sfm") == "demo"


def test_variant_names_fit_the_workflow_wildcard():
    import re

    for v in (0.25, -1, "fast", 1e-3):
        assert re.fullmatch(r"[A-Za-z0-9_-]+", variant_name("refine.strength", v))


def _tsv(path: Path, seconds: list[float], cpu: bool = True) -> None:
    """A benchmark TSV whose cpu_time is half the wall seconds (without the column: older Snakemake)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = "".join(f"{s}\t0:00:01\t100" + (f"\t{s / 2}" if cpu else "") + "\n" for s in seconds)
    path.write_text("s\th:m:s\tmax_rss" + ("\tcpu_time" if cpu else "") + "\n" + rows)


def test_benchmark_seconds_averages_repeats_and_sums_files(tmp_path):
    _tsv(tmp_path / "a.tsv", [2.0, 4.0])
    _tsv(tmp_path / "b.tsv", [1.5])
    assert benchmark_seconds([tmp_path / "a.tsv", tmp_path / "b.tsv"]) == pytest.approx(4.5)
    assert benchmark_seconds([tmp_path / "a.tsv", tmp_path / "b.tsv"], "cpu_time") == pytest.approx(2.25)
    _tsv(tmp_path / "old.tsv", [1.0], cpu=False)
    assert benchmark_seconds([tmp_path / "a.tsv", tmp_path / "old.tsv"], "cpu_time") is None
    (tmp_path / "c.tsv").write_text("x\ty\n1\t2\n")
    with pytest.raises(ValueError, match="c.tsv"):
        benchmark_seconds([tmp_path / "c.tsv"])


def _metrics(value: float, psnr: float | None) -> dict:
    m = {"gt/amplitude_w1": {"value": value, "available": True}}
    m["multiview/psnr_novel"] = ({"value": psnr, "available": True} if psnr is not None
                                 else {"value": None, "available": False, "reason": "no weights"})
    return {"metrics": m}


def test_report_rows_csv_and_plot(tmp_path):
    res = tmp_path / "results"
    for s, sec in (("static", 100.0), ("views", 5.0), ("masks", 3.0)):
        _tsv(res / "demo" / "benchmarks" / f"{s}.tsv", [sec])
    _tsv(res / "demo" / "full" / "benchmarks" / "round1" / "update.tsv", [60.0])
    _tsv(res / "demo" / "full" / "benchmarks" / "round1" / "render_v00.tsv", [10.0])
    _tsv(res / "demo" / "full" / "benchmarks" / "eval.tsv", [999.0])  # evaluation is not part of the cost
    _tsv(res / "demo" / "t40" / "benchmarks" / "round1" / "update.tsv", [20.0])
    pts = [SweepPoint("t40", "update.steps", 40, {}), SweepPoint("full", "update.steps", 120, {})]
    rows = report_rows(pts, res, "demo", {"demo/t40": _metrics(0.01, None), "demo/full": _metrics(0.004, 30.0)})
    assert [r["seconds"] for r in rows] == [128.0, 178.0]
    assert [r["variant_seconds"] for r in rows] == [20.0, 70.0]
    assert [r["cpu_seconds"] for r in rows] == [64.0, 89.0] and rows[0]["variant_cpu_seconds"] == 10.0
    assert rows[0]["multiview/psnr_novel"] is None and rows[1]["multiview/psnr_novel"] == 30.0
    path = write_csv(rows, tmp_path / "tradeoff" / "demo.csv")
    with open(path) as f:
        got = list(csv.DictReader(f))
    assert [g["value"] for g in got] == ["40", "120"]
    assert got[0]["multiview/psnr_novel"] == "n/a"
    png = plot_knob(rows, "update.steps", ["gt/amplitude_w1", "multiview/psnr_novel"], tmp_path / "p.png")
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] == 2 * 360
    assert (img < 250).any()  # something was drawn
    with pytest.raises(FileNotFoundError, match="nothing"):
        report_rows([SweepPoint("nothing", "update.steps", 1, {})], res, "demo", {"demo/nothing": _metrics(0, 0)})


def test_a_derived_scene_counts_its_own_stages_and_the_base_scenes_upstream(tmp_path):
    res = tmp_path / "results"
    for s, sec in (("static", 100.0), ("views", 5.0), ("masks", 3.0)):
        _tsv(res / "demo" / "benchmarks" / f"{s}.tsv", [sec])
    st, vw = "demo--tradeoff-static-iterations-500", "demo--tradeoff-views-height-96-width-128"
    for s, sec in (("static", 40.0), ("views", 4.0), ("masks", 2.0)):
        _tsv(res / st / "benchmarks" / f"{s}.tsv", [sec])
    for s, sec in (("views", 1.0), ("masks", 0.5)):
        _tsv(res / vw / "benchmarks" / f"{s}.tsv", [sec])
    for scene in (st, vw):
        _tsv(res / scene / "full" / "benchmarks" / "round1" / "update.tsv", [10.0])
    pts = sweep_points({"static.iterations": [500], "views": [{"width": 128, "height": 96}]}, "full",
                       {"full": {}}, base_value=BASE.get)
    rows = report_rows(pts, res, "demo", {f"{st}/full": _metrics(0.02, None), f"{vw}/full": _metrics(0.03, None)})
    assert [r["seconds"] for r in rows] == [56.0, 111.5]  # 40+4+2+10; the base's static 100 + 1+0.5+10
    assert [r["run"] for r in rows] == [f"{st}/full", f"{vw}/full"]
    assert json.loads(rows[1]["value"]) == {"width": 128, "height": 96}


# ---- the Pareto front ----

def test_pareto_front_lower_and_higher_is_better():
    times = [10.0, 20.0, 30.0, 40.0, 25.0]
    err = [0.5, 0.3, 0.35, 0.1, 0.3]  # 30 s is beaten by 20 s; 25 s ties 20 s's value but is slower
    assert pareto_front(times, err, lower_is_better=True) == [0, 1, 3]
    psnr = [20.0, 25.0, 24.0, 30.0, 26.0]
    assert pareto_front(times, psnr, lower_is_better=False) == [0, 1, 4, 3]  # fastest first


def test_pareto_front_ties_duplicates_and_degenerate_cases():
    assert pareto_front([5.0], [1.0], True) == [0]
    assert pareto_front([], [], True) == []
    # duplicates (the base point under several knobs) are all on it
    assert pareto_front([10.0, 10.0, 5.0], [0.2, 0.2, 0.9], True) == [2, 0, 1]
    # equal times: only the best value(s)
    assert pareto_front([3.0, 3.0, 3.0, 3.0], [0.4, 0.1, 0.7, 0.1], True) == [1, 3]
    assert pareto_front([3.0, 3.0, 3.0], [0.4, 0.1, 0.7], False) == [2]
    # equal values: only the fastest
    assert pareto_front([3.0, 1.0, 2.0], [0.5, 0.5, 0.5], True) == [1]


def test_pareto_front_leaves_out_missing_values():
    nan = float("nan")
    assert pareto_front([1.0, 2.0, 3.0, 4.0], [nan, 0.5, None, 0.1], True) == [1, 3]
    assert pareto_front([nan, 2.0, None], [0.0, 0.5, 0.0], True) == [1]
    assert pareto_front([1.0, 2.0], [nan, None], False) == []


def _rows() -> list[dict]:
    """Report rows: the base (full) appears under both knobs."""
    def row(knob, value, run, sec, w1, psnr, ratio):
        return {"knob": knob, "value": value, "run": run, "seconds": sec, "cpu_seconds": sec / 2,
                "gt/amplitude_w1": w1, "multiview/psnr_novel": psnr, "gt/rms_amplitude_ratio": ratio}

    return [row("update.steps", 40, "demo/t40", 100.0, 0.010, None, 0.6),
            row("update.steps", 120, "demo/full", 150.0, 0.004, 30.0, 0.9),
            row("update.num_bases", 6, "demo/k6", 160.0, 0.006, 31.0, 0.8),
            row("update.num_bases", 12, "demo/full", 150.0, 0.004, 30.0, 0.9),
            row("static.iterations", 500, "demo--tradeoff-static-iterations-500/full", 90.0, 0.012, 27.0, 1.0)]


DIRS = {"gt/amplitude_w1": False, "multiview/psnr_novel": True, "gt/rms_amplitude_ratio": None}
SHOWN = ["gt/amplitude_w1", "multiview/psnr_novel", "gt/rms_amplitude_ratio", "missing"]


def test_metric_directions_from_metrics_json():
    metrics = {"a": {"metrics": {"x": {"higher_is_better": False}, "r": {"higher_is_better": None}}},
               "b": {"metrics": {"y": {"higher_is_better": True}, "r": {"higher_is_better": None}}}}
    assert metric_directions(metrics) == {"x": False, "r": None, "y": True}


def test_report_fronts_mark_rows_and_list_settings():
    rows = _rows()
    fronts = report_fronts(rows, SHOWN, DIRS)
    assert set(fronts) == {"gt/amplitude_w1", "multiview/psnr_novel"}  # no direction / no value: no front
    assert fronts["gt/amplitude_w1"] == [4, 0, 1, 3]  # 90 s, 100 s, then the base under both knobs
    assert fronts["multiview/psnr_novel"] == [4, 1, 3, 2]
    mark_fronts(rows, fronts)
    assert [r["front"] for r in rows] == ["gt/amplitude_w1", "gt/amplitude_w1; multiview/psnr_novel",
                                          "multiview/psnr_novel", "gt/amplitude_w1; multiview/psnr_novel",
                                          "gt/amplitude_w1; multiview/psnr_novel"]
    text = front_section(rows, fronts, DIRS, SHOWN)
    print(text)
    assert text.startswith("## On the front")
    w1 = text[text.index("### gt/amplitude_w1"):text.index("### multiview/psnr_novel")]
    assert "(lower is better)" in w1
    items = [ln for ln in w1.splitlines() if ln.startswith("- ")]
    assert items == ["- static.iterations = 500 (`demo--tradeoff-static-iterations-500/full`): 90 s (CPU 45 s), "
                     "gt/amplitude_w1 0.012",
                     "- update.steps = 40 (`demo/t40`): 100 s (CPU 50 s), gt/amplitude_w1 0.01",
                     "- update.steps = 120, update.num_bases = 12 (`demo/full`): 150 s (CPU 75 s), "
                     "gt/amplitude_w1 0.004"]
    assert "### multiview/psnr_novel (higher is better)" in text
    assert "### gt/rms_amplitude_ratio: no front, it has no direction" in text
    assert "### missing: no front, no point" in text
    md = markdown_report(rows, SHOWN, fronts, DIRS)
    table = [ln for ln in md.splitlines() if ln.startswith("| ")]
    assert table[0] == ("| knob | value | run | seconds | cpu_seconds | gt/amplitude_w1 | multiview/psnr_novel | "
                        "gt/rms_amplitude_ratio |")
    assert table[3] == "| update.num_bases | 6 | demo/k6 | 160 | 80 | 0.006 | 31 ✓ | 0.8 |"
    assert table[1].split(" | ")[6] == "n/a"  # t40 has no PSNR
    assert md.rstrip().endswith(text.rstrip())


def test_plot_draws_the_front(tmp_path):
    rows = _rows()
    fronts = report_fronts(rows, SHOWN, DIRS)
    plain = cv2.imread(str(plot_knob(rows, "update.steps", SHOWN[:2], tmp_path / "a.png")))
    marked = cv2.imread(str(plot_knob(rows, "update.steps", SHOWN[:2], tmp_path / "b.png", fronts=fronts)))
    assert plain.shape == marked.shape == (260, 720, 3)

    def green(img):
        b, g, r = (img[..., i].astype(int) for i in range(3))
        return int(((g - r > 60) & (g - b > 60)).sum())

    assert green(plain) == 0 and green(marked) > 100


def test_stage_writes_the_front_into_csv_markdown_and_log(tmp_path, caplog):
    import logging

    from anigs.stages.tradeoff import Outputs, report

    res = tmp_path / "results"
    _tsv(res / "demo" / "benchmarks" / "static.tsv", [100.0])
    for variant, sec in (("full", 50.0), ("t40", 20.0), ("k6", 60.0)):
        _tsv(res / "demo" / variant / "benchmarks" / "round1" / "update.tsv", [sec])
    vals = {"full": (0.004, 30.0), "t40": (0.01, None), "k6": (0.006, 31.0)}
    for variant, (w1, psnr) in vals.items():
        m = _metrics(w1, psnr)
        m["metrics"]["gt/amplitude_w1"]["higher_is_better"] = False
        m["metrics"]["multiview/psnr_novel"]["higher_is_better"] = True
        path = res / "demo" / variant / "eval" / "metrics.json"
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(m))
    pts = [SweepPoint("t40", "update.steps", 40, {}), SweepPoint("full", "update.steps", 120, {}),
           SweepPoint("k6", "update.num_bases", 6, {}), SweepPoint("full", "update.num_bases", 12, {})]
    with caplog.at_level(logging.INFO, logger="anigs.reports.tradeoff"):
        out = report("demo", pts, res, Outputs(tmp_path / "tradeoff"), ["gt/amplitude_w1", "multiview/psnr_novel"])
    with open(out) as f:
        got = list(csv.DictReader(f))
    assert [g["front"] for g in got] == ["gt/amplitude_w1", "gt/amplitude_w1; multiview/psnr_novel",
                                         "multiview/psnr_novel", "gt/amplitude_w1; multiview/psnr_novel"]
    md = (tmp_path / "tradeoff" / "demo.md").read_text(encoding="utf-8")
    assert "## On the front" in md and "- update.num_bases = 6 (`demo/k6`): 160 s" in md
    assert {p.name for p in (tmp_path / "tradeoff").glob("*.png")} == {"demo_update-steps.png",
                                                                        "demo_update-num_bases.png"}
    assert "On the front" in caplog.text and "update.steps = 40 (`demo/t40`): 120 s" in caplog.text
