"""Paper tables from metrics.json records: structure, n/a footnotes, averages, bold, three formats."""
from __future__ import annotations

import csv
import io
import json

import pytest

from anigs.io import write_json
from anigs.metrics import metric_record, not_available
from anigs.reports.tables import (SCHEMA, ablation_table, build_tables, fvd_table, load_metrics, multiview_table,
                          to_csv, to_latex, to_markdown, weightfree_table, write_tables)

SCENES = ["fireplace", "garden"]


def rec(scene, method="Ours", variant="full", dataset="anigs", **metrics):
    return {"schema": SCHEMA, "scene": scene, "method": method, "variant": variant, "dataset": dataset,
            "metrics": metrics, "_path": f"{scene}-{method}-{variant}"}


def fvd(v, n=250):
    return metric_record(v, False, "", {"crop": 256}, {"test": n, "reference": n}, feature_dim=400)


def paper_like_records():
    out = []
    vals = {"Ours": (374.49, 403.89), "Gaussians2Life": (1127.78, 876.60), "PhysDreamer": (943.56, 957.12)}
    for m, (a, b) in vals.items():
        for s, v in zip(SCENES, (a, b)):
            out.append(rec(s, m, **{"fvd/ltx": fvd(v), "fvd/cosmos": fvd(v * 0.6)}))
    # PhysDreamer has no cosmos reference on garden (weights missing)
    out[-1]["metrics"]["fvd/cosmos"] = not_available("FVD (I3D): weights file not found at /w/i3d.pt", False)
    return out


def test_fvd_table_structure_best_and_average():
    t = fvd_table(paper_like_records())
    assert t.header == ["FVD", "fireplace", "garden", "Avg."]
    assert list(t.sections.values()) == ["FVD-LTX", "FVD-Cosmos", "FID-LTX"]  # FID: n/a, not computed
    labels = [r[0] for r in t.rows]
    assert labels == ["Ours", "Gaussians2Life", "PhysDreamer"] * 3
    ours = t.rows[0][1]
    assert ours[2].value == pytest.approx((374.49 + 403.89) / 2)
    assert all(c.bold for c in ours)  # lowest FVD in every column
    assert not any(c.bold for c in t.rows[1][1])
    phys_cosmos = t.rows[5][1]
    assert phys_cosmos[1].value is None and phys_cosmos[2].value is None  # n/a and its average
    reasons = [t.footnotes[c.note - 1] for c in phys_cosmos[1:]]
    assert "weights file not found" in reasons[0] and "average" in reasons[1]


def test_formats_carry_na_footnotes_and_bold():
    t = fvd_table(paper_like_records())
    md = to_markdown(t)
    assert "**374.49**" in md and "n/a<sup>1</sup>" in md and "weights file not found" in md
    assert md.count("\n|") == 14  # header, rule, 3 section rows, 9 data rows
    tex = to_latex(t)
    assert r"\textbf{374.49}" in tex and "n/a$^{1}$" in tex and r"\begin{tabular}{lccc}" in tex
    for line in tex.splitlines():
        if line.endswith(r"\\") and "&" in line:
            assert line.count("&") == 3, line
    rows = list(csv.reader(io.StringIO(to_csv(t))))
    assert rows[0] == ["block", "FVD", "fireplace", "garden", "Avg."]
    assert rows[1][:3] == ["FVD-LTX", "Ours", "374.49"]
    assert rows[6][:2] == ["FVD-Cosmos", "PhysDreamer"] and rows[6][3] == "n/a [1]"
    notes = [r[0] for r in rows if r and r[0].startswith("# [")]
    assert notes[0].startswith("# [1]") and "weights file not found" in notes[0]
    assert any("FID-LTX not computed" in n for n in notes)


def test_missing_record_is_na_with_reason():
    recs = paper_like_records()[:-1]  # PhysDreamer garden file missing entirely
    t = fvd_table(recs)
    cell = t.rows[2][1][1]
    assert cell.value is None and "no metrics file" in t.footnotes[cell.note - 1]


def test_ablation_table_order_labels_and_best():
    vals = {"no_dataset_update": 533.95, "no_view_expansion": 511.46, "no_composed_v2v": 420.77,
            "opt_all": 473.14, "opt_deform_only": 450.22, "full": 374.49}
    recs = [rec("fireplace", variant=v, **{"fvd/ltx": fvd(x)}) for v, x in vals.items()]
    recs = [r for r in recs if r["variant"] != "opt_all"]  # one variant not run
    t = ablation_table(recs)
    assert [r[0] for r in t.rows] == ["w/o dataset--model update", "w/o viewpoint expansion", "w/o ComposedV2V",
                                      "w/ opt. all param.", "w/ opt. deformation only", "Ours (full model)"]
    assert t.rows[-1][1][0].bold and t.rows[-1][1][0].value == 374.49
    assert t.rows[3][1][0].value is None and "opt_all" in t.footnotes[t.rows[3][1][0].note - 1]
    assert r"\textsc{ComposedV2V}" in to_latex(t)


def test_multiview_table_rows():
    recs = [rec(s, **{"multiview/psnr_capture": metric_record(27.4 + i, True, "dB"),
                      "multiview/psnr_novel": metric_record(25.9 + i, True, "dB")}) for i, s in enumerate(SCENES)]
    recs.append(rec("garden", variant="no_composed_v2v",
                    **{"multiview/psnr_novel": not_available("static fit unavailable", True, "dB")}))
    t = multiview_table(recs)
    assert t.header == ["PSNR", "fireplace", "garden"]
    assert t.rows[0][0] == "Original capture" and [c.value for c in t.rows[0][1]] == [27.4, 28.4]
    assert t.rows[1][0] == "Ours novel time" and [c.value for c in t.rows[1][1]] == [25.9, 26.9]
    assert "w/o ComposedV2V" in t.rows[2][0]
    assert all(c.value is None for c in t.rows[2][1])


def test_weightfree_table_every_variant():
    recs = [rec("demo", variant=v, static_abs_diff=metric_record(x, False), dynamic_abs_diff=metric_record(0.05, True),
                **{"gt/rms_amplitude_ratio": metric_record(0.9, True)})
            for v, x in (("full", 0.001), ("no_composed_v2v", 0.004))]
    recs.append(rec("demo", method="Baseline", static_abs_diff=not_available("no dynamic masks given", False)))
    t = weightfree_table(recs)
    assert t.header[:2] == ["scene", "method"] and "static |dI/dt|" in t.header and "GT amp. ratio" in t.header
    assert len(t.rows) == 3
    assert t.rows[0][1][0].bold and not t.rows[1][1][0].bold
    assert t.rows[2][1][0].value is None
    csv_rows = list(csv.reader(io.StringIO(to_csv(t))))
    assert csv_rows[1][:2] == ["demo", "Ours"] and csv_rows[2][1] == "Ours w/o ComposedV2V"


def test_weightfree_bolds_each_column_in_its_direction_with_significant_digits():
    """The share of still pixels is best high, leakage and GT distances best low; ~1e-6 leakage is
    printed with significant digits, not as 0.0000; the GT amplitude ratio (best at 1) is not bolded."""
    recs = [rec("demo", method=m, static_abs_diff=metric_record(a, False),
                static_outside_mask_still=metric_record(still, True),
                **{"gt/frequency_w1": metric_record(w, False), "gt/rms_amplitude_ratio": metric_record(r, None)})
            for m, a, still, w, r in (("Ours", 2.08e-6, 1.0, 0.016, 0.83), ("Other", 4.9e-6, 0.99866, 0.051, 1.0))]
    t = weightfree_table(recs)
    col = {h: i for i, h in enumerate(t.header[2:])}
    ours, other = t.rows[0][1], t.rows[1][1]
    assert ours[col["static |dI/dt|"]].bold and ours[col["still outside mask"]].bold and ours[col["GT freq. W1"]].bold
    assert not any(c.bold for c in other[:3]) and not other[col["GT amp. ratio"]].bold
    md = to_markdown(t)
    assert "2.08e-06" in md and "0.99866" in md and "0.0000 " not in md


def test_load_metrics_checks_and_write_tables(tmp_path):
    paths = []
    for i, r in enumerate(paper_like_records()):
        r = {k: v for k, v in r.items() if k != "_path"}
        p = tmp_path / f"m{i}.json"
        write_json(p, r)
        paths.append(p)
    records = load_metrics(paths)
    out = write_tables(records, tmp_path / "tables")
    names = sorted(p.name for p in out)
    for stem in ("table1_fvd", "table3_multiview", "table5_ablation", "weightfree"):
        for ext in ("csv", "md", "tex"):
            assert f"{stem}.{ext}" in names
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"schema": "other", "scene": "x", "method": "y", "metrics": {}}))
    with pytest.raises(ValueError, match="schema"):
        load_metrics([bad])
    bad.write_text(json.dumps({"schema": SCHEMA, "scene": "x", "metrics": {}}))
    with pytest.raises(ValueError, match="'method'"):
        load_metrics([bad])
    with pytest.raises(ValueError, match="two metrics files"):
        fvd_table(records + records[:1])


def test_second_dataset_gets_table2():
    recs = paper_like_records() + [rec("gazebo", dataset="dl3dv", **{"fvd/ltx": fvd(413.59)})]
    names = [t.name for t in build_tables(recs)]
    assert names[:2] == ["table1_fvd", "table2_fvd_dl3dv"]


def test_table1_has_fid_blocks_with_the_reason_when_not_computed():
    recs = paper_like_records()
    recs[0]["metrics"]["fid/ltx"] = {"available": False, "value": None, "higher_is_better": False,
                                      "reason": "no weights path for fid (eval.inception_path)"}
    recs[1]["metrics"]["fid/ltx"] = {"available": True, "value": 12.5, "higher_is_better": False}
    t = fvd_table(recs)
    labels = list(t.sections.values())
    assert labels[-1] == "FID-LTX" and labels[0] == "FVD-LTX"
    md = to_markdown(t)
    assert "no weights path for fid" in md and "12.50" in md
    # records without any FID still get the block, each cell n/a with why
    md0 = to_markdown(fvd_table(paper_like_records()))
    assert "FID-LTX" in md0 and "FID-LTX not computed" in md0


def test_tables_cli(tmp_path):
    from anigs.cli import main

    r = {k: v for k, v in paper_like_records()[0].items() if k != "_path"}
    write_json(tmp_path / "m.json", r)
    assert main(["tables", "--metrics", str(tmp_path / "m.json"), "--out", str(tmp_path / "t")]) == 0
    assert "374.49" in (tmp_path / "t" / "table1_fvd.md").read_text()


def _tiny_inputs(tmp_path):
    """Clips + masks + reference clips + a tiny animated model with cameras, images and points."""
    import numpy as np
    import torch

    from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
    from anigs.animate.deform import DCTDeformation, save_model
    from anigs.gaussians import Gaussians
    from anigs.io import write_npz
    from anigs.images import write_mask_png
    from anigs.render import render_gaussians
    from anigs.video import save_clip

    rng = np.random.default_rng(0)
    T, H, W = 12, 32, 40
    x = np.arange(W)
    for folder, n in (("final", 2), ("ref", 3)):
        for v in range(n):
            bg = rng.uniform(0, 1, (H, W, 3)).astype(np.float32)
            clip = np.repeat(bg[None], T, 0)
            for t in range(T):
                clip[t, :, W // 2:] = (0.5 + 0.4 * np.sin(2 * np.pi * (x[W // 2:] / 8 - 0.25 * t)))[None, :, None]
            save_clip(tmp_path / folder / ("clips" if folder == "final" else "") / f"view_{v}.npz", clip)
            if folder == "final":
                m = np.zeros((H, W), bool)
                m[:, W // 2:] = True
                write_mask_png(tmp_path / "masks" / f"view_{v}.png", m)
    pts = rng.uniform(-1, 1, (300, 3)).astype(np.float32)
    cols = rng.uniform(0, 1, (300, 3)).astype(np.float32)
    gs = Gaussians.from_points(torch.from_numpy(pts), torch.from_numpy(cols), 0.12, opacity=0.9)
    gs.save_ply(tmp_path / "static" / "canonical.ply")
    d = DCTDeformation(torch.arange(100), T, 3, rotation=False, num_gaussians=gs.num)
    with torch.no_grad():
        d.pos_coeffs.normal_(0, 0.05, generator=torch.Generator().manual_seed(0))
    save_model(tmp_path / "model" / "model.pt", d, gs)
    cams = [Camera(intrinsics_from_fov(60, 32, 24), look_at((4 * np.cos(a), 4 * np.sin(a), 1.5), (0, 0, 0)), 32, 24,
                   f"img_{i:03d}.png") for i, a in enumerate(np.linspace(0, 2 * np.pi, 6, endpoint=False))]
    save_cameras(tmp_path / "sfm" / "cameras.json", cams)
    from anigs.video import save_png

    for c in cams:
        with torch.no_grad():
            save_png(tmp_path / "sfm" / "images" / c.name, render_gaussians(gs, c)[0].clamp(0, 1))
    write_npz(tmp_path / "sfm" / "points.npz", xyz=pts, rgb=cols)
    return tmp_path


def test_eval_cli_writes_schema_and_tables_read_it(tmp_path):
    """anigs eval (weight-free, FVD with a stand-in I3D, FID missing, multiview glue) -> anigs tables."""
    import numpy as np
    import torch

    from anigs.cli import main
    from anigs.io import read_json

    d = _tiny_inputs(tmp_path)

    class StandIn(torch.nn.Module):
        def forward(self, x: torch.Tensor, rescale: bool = False, resize: bool = False,
                    return_features: bool = False) -> torch.Tensor:
            return torch.cat([x.mean(dim=(2, 3, 4)), x.std(dim=(2, 3, 4))], dim=1)

    torch.jit.script(StandIn()).save(str(d / "i3d.pt"))
    params = {"i3d_path": str(d / "i3d.pt"), "inception_path": str(d / "missing.pt"), "fvd_clip_frames": 8,
              "fvd_window_stride": 2, "flow_preset": "ultrafast",
              "multiview_fit": {"iterations": 10, "sh_degree": 0, "device": "cpu"}}
    out = d / "eval" / "metrics.json"
    argv = ["eval", "--final", str(d / "final"), "--masks", str(d / "masks"), "--reference",
            f"procedural={d / 'ref'}", "--model", str(d / "model"), "--static", str(d / "static"),
            "--sfm", str(d / "sfm"), "--scene", "demo", "--out", str(out.parent), "--params", json.dumps(params)]
    assert main(argv) == 0
    rec = read_json(out)
    assert rec["schema"] == SCHEMA and rec["scene"] == "demo" and rec["variant"] == "full"
    m = rec["metrics"]
    fvd_rec = m["fvd/procedural"]
    assert fvd_rec["available"] and np.isfinite(fvd_rec["value"]) and fvd_rec["feature_dim"] == 6
    assert fvd_rec["samples"] == {"test": 2 * 3, "reference": 3 * 3}  # windows 0,2,4 of 12 frames per clip
    assert not m["fid/procedural"]["available"] and str(d / "missing.pt") in m["fid/procedural"]["reason"]
    assert m["fid/procedural"]["expected_path"] == str(d / "missing.pt")
    assert m["static_abs_diff"]["value"] == 0.0 and m["dominant_freq"]["value"] == pytest.approx(0.25, abs=1 / 12)
    assert m["static_abs_diff"]["samples"]["views"] == 2
    for k in ("multiview/psnr_capture", "multiview/psnr_novel"):
        assert m[k]["available"] and m[k]["samples"] == {"train_views": 3, "eval_views": 3}
    assert m["multiview/psnr_novel"]["protocol"]["t"] == round(21 * 11 / 120)
    # an ablation variant with the weights missing altogether
    params2 = dict(params, i3d_path="", multiview=False)
    out2 = d / "eval_abl" / "metrics.json"
    argv2 = [a if a != str(out.parent) else str(out2.parent) for a in argv]
    argv2 = argv2[:argv2.index("--params")] + ["--variant", "no_composed_v2v", "--params", json.dumps(params2)]
    assert main(argv2) == 0
    m2 = read_json(out2)["metrics"]
    assert not m2["fvd/procedural"]["available"] and "no weights path" in m2["fvd/procedural"]["reason"]
    assert not any(k.startswith("multiview/") for k in m2)
    assert main(["tables", "--metrics", str(out), str(out2), "--out", str(d / "tables")]) == 0
    abl = (d / "tables" / "table5_ablation.md").read_text()
    assert "Procedural" in abl and "no weights path" in abl
    mv = (d / "tables" / "table3_multiview.csv").read_text()
    assert "Original capture" in mv and "Ours novel time" in mv
    wf = (d / "tables" / "weightfree.csv").read_text()
    assert "Ours w/o ComposedV2V" in wf


def test_eval_fid_reference_pools_paths(tmp_path):
    """--fid-reference PRIOR=PATH (repeated) pools clips for FID only; FVD keeps --reference."""
    import torch

    from anigs.metrics.config import EvalConfig

    from anigs.metrics.suite import ClipInputs, evaluate_variant
    from anigs.stages.masks import Outputs as MasksOutputs

    d = _tiny_inputs(tmp_path)

    class StandInInception(torch.nn.Module):
        def forward(self, x: torch.Tensor, return_features: bool = False) -> torch.Tensor:
            return torch.cat([x.mean(dim=(2, 3)), x.std(dim=(2, 3))], dim=1)

    torch.jit.script(StandInInception()).save(str(d / "inc.pt"))
    cfg = EvalConfig.from_dict({"inception_path": str(d / "inc.pt"), "fid_size": 32, "multiview": False,
                                "i3d_path": ""})  # FVD off: its reason says so
    m = evaluate_variant(cfg, ClipInputs([d / "final" / "clips"], MasksOutputs(d / "masks"), {"ltx": [d / "ref"]},
                                 fid_references={"ltx": [d / "ref", d / "final" / "clips"]}))
    assert m["fid/ltx"]["available"] and m["fid/ltx"]["samples"] == {"test": 2 * 12, "reference": 5 * 12}
    assert m["fid/ltx"]["feature_dim"] == 6
    assert not m["fvd/ltx"]["available"] and "no weights path" in m["fvd/ltx"]["reason"]
    with pytest.raises(ValueError, match="unknown keys"):
        EvalConfig.from_dict({"fvd_crop": 1})
    with pytest.raises(ValueError, match="flow_preset"):
        EvalConfig.from_dict({"flow_preset": "slow"})


def test_eval_in_two_parts_gives_the_same_record_as_in_one(tmp_path, caplog):
    """--part model and --part clips, joined by --merge: the record of one --part all run; halves checked."""
    from anigs.cli import main
    from anigs.io import read_json, write_json

    d = _tiny_inputs(tmp_path)
    params = json.dumps({"flow_preset": "ultrafast", "multiview_fit": {"iterations": 10, "sh_degree": 0,
                                                                       "device": "cpu"}})
    common = ["--masks", str(d / "masks"), "--model", str(d / "model"), "--static", str(d / "static"),
              "--sfm", str(d / "sfm"), "--scene", "demo", "--params", params]
    final = ["--final", str(d / "final")]
    assert main(["eval", *final, *common, "--out", str(d / "one")]) == 0
    assert main(["eval", "--part", "model", *common, "--out", str(d / "two")]) == 0
    assert main(["eval", "--part", "clips", *final, *common, "--out", str(d / "two")]) == 0
    assert main(["eval", "--merge", "--out", str(d / "two")]) == 0
    one, half, clips, two = (read_json(d / f) for f in ("one/metrics.json", "two/model_metrics.json",
                                                        "two/clip_metrics.json", "two/metrics.json"))
    assert half["part"] == "model" and set(half["metrics"]) == {k for k in one["metrics"] if k.startswith("multiview/")}
    assert clips["part"] == "clips" and not any(k.startswith("multiview/") for k in clips["metrics"])
    assert one["part"] == two["part"] == "all"
    assert list(two["metrics"]) == list(one["metrics"])
    assert {k: m["value"] for k, m in two["metrics"].items()} == {k: m["value"] for k, m in one["metrics"].items()}
    assert two["inputs"] == one["inputs"] and clips["inputs"]["images"] is None
    # a model half is no table record; halves of different evaluations, or not halves, are refused
    assert main(["tables", "--metrics", str(d / "two" / "model_metrics.json"), "--out", str(d / "tables")]) == 1
    assert "holds only the model's metrics" in caplog.text
    (d / "x").mkdir()
    write_json(d / "x" / "clip_metrics.json", clips)
    write_json(d / "x" / "model_metrics.json", dict(half, variant="no_composed_v2v"))
    assert main(["eval", "--merge", "--out", str(d / "x")]) == 1
    assert "are of different evaluations" in caplog.text
    write_json(d / "x" / "model_metrics.json", one)
    assert main(["eval", "--merge", "--out", str(d / "x")]) == 1
    assert "model_metrics.json is not the record of an `anigs eval --part model` run" in caplog.text
    assert not (d / "x" / "metrics.json").exists()
    assert main(["eval", *final, "--out", str(d / "x")]) == 1
    assert "--scene is required" in caplog.text
