"""FVD-GT in the tables: joined from its own records, a Table 1 block with spread and clip counts
for methods and ablations, the no-motion control, the detail table, n/a on real captures."""
from __future__ import annotations

import pytest

from anigs.io import write_json
from anigs.metrics import metric_record
from anigs.metrics.records import merge_records as merge
from anigs.reports.tables import SCHEMA, build_tables, fvd_table, load_metrics, to_csv, to_latex, to_markdown


def _gt(v, std, n=128):
    return metric_record(v, False, "", {"views": "64"}, {"test": n, "reference": n, "views": 64}, feature_dim=400,
                         bootstrap={"std": std, "interval": [v - 2 * std, v + 2 * std], "resamples": 200},
                         still_control=metric_record(900.0, False, "", {}, {"test": n, "reference": n, "views": 64},
                                                     bootstrap={"std": 30.0, "interval": [850.0, 950.0]}))


def _rec(method, variant, part="all", gt_dir="results/demo/capture/gt", **metrics):
    return {"schema": SCHEMA, "scene": "demo", "dataset": "anigs", "method": method, "variant": variant,
            "part": part, "inputs": {"gt_dir": gt_dir}, "metrics": metrics}


def _files(tmp_path):
    main = [("Ours", "full"), ("Ours", "no_composed_v2v"), ("Gaussians2Life", "full"), ("PhysDreamer", "full")]
    vals = {"full": 400.0, "no_composed_v2v": 450.0}
    paths = []
    for i, (m, v) in enumerate(main):
        p = tmp_path / f"m{i}.json"
        write_json(p, _rec(m, v, static_abs_diff=metric_record(1e-6, False)))
        q = tmp_path / f"g{i}.json"
        write_json(q, _rec(m, v, part="fvd_gt", **{"fvd/gt": _gt(vals.get(v, 800.0 + i), 10.0 + i)}))
        paths += [p, q]
    return paths


def test_fvd_gt_records_join_their_metrics(tmp_path):
    recs = load_metrics(_files(tmp_path))
    assert len(recs) == 4
    assert all("fvd/gt" in r["metrics"] and "static_abs_diff" in r["metrics"] for r in recs)


def test_table1_fvd_gt_block(tmp_path):
    t = fvd_table(load_metrics(_files(tmp_path)))
    names = list(t.sections.values())
    assert names[0] == "FVD-LTX" and names[1].startswith("FVD-GT") and names[-1] == "FID-LTX"
    start = list(t.sections)[1]
    rows = t.rows[start:start + 5]
    labels = [r[0] for r in rows]
    assert labels == ["Ours", "Gaussians2Life", "PhysDreamer", "Ours (w/o ComposedV2V)",
                      "Static scene, no motion (control)"]
    assert rows[0][1][0].text() == "400.00 ± 10.00 (128)" and rows[0][1][0].bold
    assert rows[3][1][0].text() == "450.00 ± 11.00 (128)" and not rows[3][1][0].bold
    assert rows[4][1][0].text() == "900.00 ± 30.00 (128)" and not rows[4][1][0].bold
    # the FVD-LTX block stays n/a with its reason
    ltx = t.rows[0][1][0]
    assert ltx.value is None and "reference clips" in t.footnotes[ltx.note - 1]
    md, tex, csv = to_markdown(t), to_latex(t), to_csv(t)
    assert "400.00 ± 10.00 (128)" in md and "400.00 ± 10.00 (128)" in tex and "FVD-GT" in csv


def test_detail_table_and_real_capture_reason(tmp_path):
    recs = load_metrics(_files(tmp_path))
    tables = {t.name: t for t in build_tables(recs)}
    d = tables["fvd_gt"]
    assert d.header[:4] == ["scene", "method", "FVD-GT", "bootstrap std"]
    first = d.rows[0][1]
    assert [c.value for c in first[:4]] == [400.0, 10.0, 380.0, 420.0] and first[4].text() == "128"
    assert sum(lbl.endswith("(control)") for lbl, _ in d.rows) == 1
    assert "VBench flicker" not in tables["weightfree"].header  # only columns some record has
    real = [_rec("Ours", "full", gt_dir=None, static_abs_diff=metric_record(1e-6, False))]
    real[0]["_path"] = "x"
    t = fvd_table(real + [dict(recs[0], scene="garden")])
    gt_row = next(i for i, s in t.sections.items() if s.startswith("FVD-GT"))
    cell = t.rows[gt_row][1][0]
    assert cell.value is None and "real capture" in t.footnotes[cell.note - 1]


def test_eval_merge_joins_an_fvd_gt_record(tmp_path):
    clips, model, gt = tmp_path / "c.json", tmp_path / "m.json", tmp_path / "g.json"
    write_json(clips, _rec("Ours", "full", part="clips", a=metric_record(1.0, False)))
    write_json(model, _rec("Ours", "full", part="model", b=metric_record(2.0, False)))
    write_json(gt, _rec("Ours", "full", part="fvd_gt", **{"fvd/gt": _gt(400.0, 10.0)}))
    out = merge(clips, model, tmp_path / "metrics.json", extra=[gt])
    assert list(out["metrics"]) == ["a", "b", "fvd/gt"] and out["part"] == "all"
    write_json(gt, _rec("PhysDreamer", "full", part="fvd_gt", **{"fvd/gt": _gt(400.0, 10.0)}))
    with pytest.raises(ValueError, match="another evaluation"):
        merge(clips, model, tmp_path / "metrics.json", extra=[gt])
