"""Paper-style tables (CSV, Markdown, LaTeX) from ``metrics.json`` files.

metrics.json schema (``"schema": "anigs-metrics/1"``), one file per (scene, method, variant)::

    {
      "schema": "anigs-metrics/1",
      "scene": "demo",            # table column
      "dataset": "anigs",         # scene group: one FVD table per dataset (Table 1, then Table 2 ...)
      "method": "Ours",           # row of Tables 1/2 (baselines: any other name)
      "variant": "full",          # ablation id (Table 5): full | no_dataset_update | no_view_expansion |
                                  #   no_composed_v2v | opt_all | opt_deform_only (others shown verbatim)
      "part": "all",              # all | clips | model: which metrics `anigs eval --part` computed (tables
                                  #   refuse a model-only record: the workflow merges it into the full one)
      "anigs_version": "0.1.0",
      "config": {...},            # the evaluation config used
      "inputs": {...},            # files evaluated (clips, references, masks, ...)
      "metrics": {
        "<name>": {
          "value": float | null,          # null when not available
          "available": bool,
          "reason": str | null,           # why not available (becomes an n/a footnote)
          "higher_is_better": bool,
          "unit": str,
          "protocol": {...},              # how it was computed (sizes, windows, presets, ...)
          "samples": {"test": n, "reference": m} | {"views": v, "frames": f} | ...,
          "warnings": [str],              # e.g. fewer samples than feature dimensions
          "feature_dim": int,             # Fréchet metrics only
          "per_view": {...}               # optional detail
        }
      }
    }

Metric names: ``fvd/<prior>``, ``fid/<prior>`` (Fréchet, lower is better); weight-free
``static_abs_diff``, ``static_drift``, ``static_flow`` (lower better), ``dynamic_abs_diff``,
``dynamic_flow`` (motion energy), ``dominant_freq``, ``spectral_centroid`` (cycles/frame),
``static_outside_mask_still`` (share of still pixels outside the dilated mask; higher better);
synthetic scene ``gt/rms_amplitude_ratio``, ``gt/amplitude_w1``, ``gt/frequency_w1``,
``gt/dominant_freq_learned``, ``gt/dominant_freq_gt``; Table 3 ``multiview/psnr_capture``,
``multiview/psnr_novel`` (and ``multiview/ssim_*``).

Tables written by :func:`write_tables`: ``table1_fvd`` (FVD, then FID, per prior block, methods as rows,
scenes + Avg as columns; the variant ``full`` of each method, or records without variant),
``table2_fvd_<dataset>`` for further datasets, ``table3_multiview`` (original capture vs
novel time), ``table5_ablation`` (FVD of one prior, variants as rows) and
``weightfree`` (every method/variant x scene). Missing or unavailable cells read ``n/a``
with a numbered footnote giving the reason; an average is given only when every scene of
the row has a value.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Sequence

from anigs.io import atomic_write_text, read_json
from anigs.reports.table_format import MISSING as MISSING  # re-exported: the n/a reason of a missing record
from anigs.reports.table_format import Cell, Table, to_csv, to_latex, to_markdown

SCHEMA = "anigs-metrics/1"

VARIANT_LABELS: dict[str, str] = {
    "no_dataset_update": "w/o dataset--model update",
    "no_view_expansion": "w/o viewpoint expansion",
    "no_composed_v2v": "w/o ComposedV2V",
    "opt_all": "w/ opt. all param.",
    "opt_deform_only": "w/ opt. deformation only",
    "full": "Ours (full model)",
}
ABLATION_ORDER = list(VARIANT_LABELS)

PRIOR_LABELS = {"ltx": "LTX", "cosmos": "Cosmos", "dynamicrafter": "DynamiCrafter", "procedural": "Procedural"}

WEIGHTFREE_COLUMNS: list[tuple[str, str]] = [
    ("static_abs_diff", "static |dI/dt|"),
    ("static_drift", "static drift"),
    ("static_flow", "static flow (px)"),
    ("dynamic_abs_diff", "dynamic |dI/dt|"),
    ("dynamic_flow", "dynamic flow (px)"),
    ("dominant_freq", "dom. freq (c/f)"),
    ("static_outside_mask_still", "still outside mask"),
    ("gt/rms_amplitude_ratio", "GT amp. ratio"),
    ("gt/amplitude_w1", "GT amp. W1"),
    ("gt/frequency_w1", "GT freq. W1"),
    ("vbench/temporal_flickering", "VBench flicker"),
    ("vbench/dynamic_degree_proxy", "dyn. degree (proxy)"),
    ("vbench/top5_flow_px", "top-5% flow (px)"),
]

FVD_GT = "fvd/gt"  # FVD against the synthetic ground-truth motion (anigs fvd_gt)
FVD_GT_PART = "fvd_gt"  # the `part` of its records, joined to the variant's metrics.json

# ----------------------------------------------------------------------------- loading

def load_metrics(paths: Iterable[str | Path]) -> list[dict[str, Any]]:
    """Read and check metrics.json files; raise ValueError naming the file and the problem."""
    records = []
    for p in paths:
        rec = read_json(p)
        if not isinstance(rec, dict):
            raise ValueError(f"{p}: expected a JSON object, got {type(rec).__name__}")
        if rec.get("schema") != SCHEMA:
            raise ValueError(f"{p}: schema is {rec.get('schema')!r}, expected {SCHEMA!r}")
        for key in ("scene", "method", "metrics"):
            if key not in rec:
                raise ValueError(f"{p}: missing key {key!r}")
        if not isinstance(rec["metrics"], dict):
            raise ValueError(f"{p}: 'metrics' must be an object")
        if rec.get("part", "all") == "model":
            raise ValueError(f"{p}: holds only the model's metrics (`anigs eval --part model`); give the "
                             f"evaluation's merged record (`anigs eval --merge`)")
        rec.setdefault("dataset", "default")
        rec.setdefault("variant", "full")
        rec["_path"] = str(p)
        records.append(rec)
    return join_parts(records)


def join_parts(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Records of ``part: fvd_gt`` (``anigs fvd_gt``) joined into the record of the same scene, dataset,
    method and variant (kept as records of their own when there is none)."""
    key = (lambda r: (r["scene"], r.get("dataset"), r["method"], r.get("variant") or "full"))
    main = {key(r): r for r in records if r.get("part", "all") != FVD_GT_PART}
    out = [r for r in records if r.get("part", "all") != FVD_GT_PART]
    for r in records:
        if r.get("part", "all") != FVD_GT_PART:
            continue
        if key(r) in main:
            m = main[key(r)]
            m["metrics"] = {**m["metrics"], **r["metrics"]}
        else:
            out.append(r)
    return out


def prior_label(prior: str) -> str:
    return PRIOR_LABELS.get(prior.lower(), prior)


def variant_label(variant: str | None) -> str:
    return VARIANT_LABELS.get(variant or "full", variant or "full")


def _bold_best(table: Table, rows: range, higher_is_better: bool) -> None:
    """Bold the best value per column among ``rows``."""
    if not table.rows:
        return
    ncol = max(len(table.rows[r][1]) for r in rows) if rows else 0
    for c in range(ncol):
        vals = [(table.rows[r][1][c].value, r) for r in rows
                if c < len(table.rows[r][1]) and table.rows[r][1][c].value is not None]
        if len(vals) < 2:
            continue
        best = max(v for v, _ in vals) if higher_is_better else min(v for v, _ in vals)
        for v, r in vals:
            if v == best:
                table.rows[r][1][c].bold = True


def _avg_cell(table: Table, cells: list[Cell], fmt: str = "{:.2f}") -> Cell:
    if cells and all(c.value is not None for c in cells):
        return Cell(sum(c.value for c in cells) / len(cells), fmt=fmt)
    return Cell(None, table.note("average needs a value for every scene of the row"), fmt=fmt)


def _metric(rec: dict[str, Any] | None, name: str) -> dict[str, Any] | None:
    if rec is None:
        return None
    m = rec["metrics"].get(name)
    if m is None:
        if name == FVD_GT:
            reason = ("FVD-GT n/a: a real capture has no ground-truth motion" if not (rec.get("inputs") or {}).get("gt_dir")
                      else "FVD-GT not computed (`snakemake tables` computes it unless fvd_gt.when is never)")
        elif name.startswith(("fvd/", "fid/")):
            kind, prior = name.split("/", 1)
            reason = (f"{kind.upper()}-{prior_label(prior)} not computed: no reference clips of prior {prior!r} "
                      "were given to anigs eval (--reference PRIOR=PATH)")
        else:
            reason = f"metric {name!r} not computed"
        return {"available": False, "value": None, "reason": reason}
    return m


def _scenes(records: Sequence[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(r["scene"] for r in records))


def _index(records: Sequence[dict[str, Any]]) -> dict[tuple[str, str, str], dict[str, Any]]:
    out = {}
    for r in records:
        key = (r["scene"], r["method"], r.get("variant") or "full")
        if key in out:
            raise ValueError(f"two metrics files for scene {key[0]!r}, method {key[1]!r}, variant {key[2]!r}: "
                             f"{out[key]['_path']} and {r['_path']}")
        out[key] = r
    return out


def _priors(records: Sequence[dict[str, Any]], kind: str = "fvd") -> list[str]:
    """The video priors whose reference clips some record was compared with (not the ground truth)."""
    names = [k.split("/", 1)[1] for r in records for k in r["metrics"] if k.startswith(kind + "/") and k != FVD_GT]
    order = {p: i for i, p in enumerate(PRIOR_LABELS)}
    return sorted(dict.fromkeys(names), key=lambda p: (order.get(p.lower(), 99), p))


# ----------------------------------------------------------------------------- the tables

def fvd_table(records: Sequence[dict[str, Any]], name: str = "table1_fvd", title: str = "") -> Table:
    """FVD per prior (blocks), then FID per prior (blocks: the paper measures FID too, with frames of
    the prior pooled over the scenes as reference, but prints no table of it); methods as rows
    (variant 'full'), scenes + Avg as columns. A block for LTX is always there (n/a with the reason
    when no evaluation computed it)."""
    recs = [r for r in records if (r.get("variant") or "full") == "full"]
    scenes = _scenes(recs)
    methods = list(dict.fromkeys(r["method"] for r in recs))
    idx = _index(recs)
    t = Table(name, title or "Quantitative evaluation (FVD and FID, lower is better)", ["FVD"] + scenes + ["Avg."])
    for kind in ("fvd", "fid"):
        for prior in _priors(recs, kind) or ["ltx"]:
            t.sections[len(t.rows)] = f"{kind.upper()}-{prior_label(prior)}"
            start = len(t.rows)
            for m in methods:
                cells = [t.cell(_metric(idx.get((s, m, "full")), f"{kind}/{prior}")) for s in scenes]
                t.rows.append((m, cells + [_avg_cell(t, cells)]))
            _bold_best(t, range(start, len(t.rows)), higher_is_better=False)
        if kind == "fvd" and any(FVD_GT in r["metrics"] or (r.get("inputs") or {}).get("gt_dir") for r in records):
            _fvd_gt_block(t, records, scenes)
    return t


def _fvd_gt_cell(t: Table, metric: dict[str, Any] | None) -> Cell:
    """An FVD-GT cell: the value, ± the bootstrap std, and (the clips per side)."""
    c = t.cell(metric)
    if c.value is not None and metric is not None:
        std = (metric.get("bootstrap") or {}).get("std")
        n = (metric.get("samples") or {}).get("test")
        c.suffix = (f" ± {std:.2f}" if std is not None else "") + (f" ({n})" if n else "")
    return c


def _fvd_gt_block(t: Table, records: Sequence[dict[str, Any]], scenes: list[str]) -> None:
    """FVD against the ground-truth motion: every method (variant full), the ablations of ours, and the
    static scene with no motion (the share of the distance that appearance alone gives)."""
    idx = _index(records)
    keys = list(dict.fromkeys((r["method"], r.get("variant") or "full") for r in records))
    keys.sort(key=lambda k: (k[1] != "full", ABLATION_ORDER.index(k[1]) if k[1] in ABLATION_ORDER else 99))
    t.sections[len(t.rows)] = "FVD-GT (± bootstrap std over views; clips per side)"
    start = len(t.rows)
    for m, v in keys:
        cells = [_fvd_gt_cell(t, _metric(idx.get((s, m, v)), FVD_GT)) for s in scenes]
        label = m if v == "full" else f"{m} ({variant_label(v)})"
        t.rows.append((label, cells + [_avg_cell(t, cells)]))
    _bold_best(t, range(start, len(t.rows)), higher_is_better=False)
    still = []
    for s in scenes:
        ctl = next((r["metrics"][FVD_GT].get("still_control") for r in records
                    if r["scene"] == s and isinstance(r["metrics"].get(FVD_GT), dict)
                    and r["metrics"][FVD_GT].get("still_control")), None)
        still.append(_fvd_gt_cell(t, ctl) if ctl else
                     Cell(None, t.note("no-motion control not computed (fvd_gt.still_control)")))
    t.rows.append(("Static scene, no motion (control)", still + [_avg_cell(t, still)]))


def fvd_gt_table(records: Sequence[dict[str, Any]]) -> Table:
    """FVD-GT in detail: per scene and method/variant the value, the bootstrap spread and the clip counts."""
    t = Table("fvd_gt", "FVD against the ground-truth motion (lower is better): bootstrap spread and clip counts",
              ["scene", "method", "FVD-GT", "bootstrap std", "90% interval low", "90% interval high",
               "clips (method)", "clips (GT)", "views"])
    controls: set[str] = set()
    for r in records:
        m = r["metrics"].get(FVD_GT)
        v = r.get("variant") or "full"
        label = r["method"] if v == "full" else f"{r['method']} {variant_label(v)}"
        rows = [(label, m)]
        if isinstance(m, dict) and m.get("still_control") and r["scene"] not in controls:
            controls.add(r["scene"])
            rows.append(("Static scene, no motion (control)", m["still_control"]))
        for lbl, met in rows:
            if met is None:
                continue
            b = met.get("bootstrap") or {}
            n = met.get("samples") or {}
            iv = b.get("interval") or [None, None]
            t.rows.append((f"{r['scene']} | {lbl}", [
                t.cell(met), Cell(b.get("std")), Cell(iv[0]), Cell(iv[1]),
                Cell(n.get("test"), fmt="{:d}"), Cell(n.get("reference"), fmt="{:d}"), Cell(n.get("views"), fmt="{:d}")]))
    return t


def multiview_table(records: Sequence[dict[str, Any]]) -> Table:
    """Table 3: multiview PSNR of a static fit to renders at a novel time vs the original capture."""
    recs = [r for r in records if any(k.startswith("multiview/") for k in r["metrics"])]
    scenes = _scenes(recs) or _scenes(records)
    t = Table("table3_multiview", "Multiview consistency: PSNR (dB, higher is better) of a 3DGS fitted to "
              "renders from 50% of the training cameras, evaluated on the rest", ["PSNR"] + scenes)
    cap = []
    for s in scenes:
        # the capture row is a property of the scene: take it from the full model's record, else any record
        cands = [r for r in recs if r["scene"] == s and "multiview/psnr_capture" in r["metrics"]]
        cands.sort(key=lambda r: (r.get("variant") or "full") != "full")
        cap.append(t.cell(cands[0]["metrics"]["multiview/psnr_capture"] if cands else None,
                          "multiview protocol not run on the original capture"))
    t.rows.append(("Original capture", cap))
    for method, variant in dict.fromkeys((r["method"], r.get("variant") or "full") for r in recs):
        label = f"{method} novel time" if variant == "full" else f"{method} ({variant_label(variant)}) novel time"
        idx = _index([r for r in recs if r["method"] == method and (r.get("variant") or "full") == variant])
        t.rows.append((label, [t.cell(_metric(idx.get((s, method, variant)), "multiview/psnr_novel"))
                               for s in scenes]))
    return t


def ablation_table(records: Sequence[dict[str, Any]], prior: str | None = None, method: str | None = None) -> Table:
    """Table 5: FVD-<prior> of the ablation variants (rows, paper order) per scene."""
    if method is None:
        with_variants = [r["method"] for r in records if (r.get("variant") or "full") != "full"]
        method = with_variants[0] if with_variants else (records[0]["method"] if records else "Ours")
    recs = [r for r in records if r["method"] == method]
    priors = _priors(recs)
    prior = prior or (priors[0] if priors else "ltx")
    scenes = _scenes(recs)
    idx = _index(recs)
    present = list(dict.fromkeys(r.get("variant") or "full" for r in recs))
    variants = [v for v in ABLATION_ORDER if v != "full"] + [v for v in present if v not in ABLATION_ORDER] + ["full"]
    t = Table("table5_ablation", f"Ablation study: FVD-{prior_label(prior)} (lower is better)",
              [f"FVD-{prior_label(prior)}"] + scenes + ["Avg."])
    for v in variants:
        cells = [t.cell(_metric(idx.get((s, method, v)), f"fvd/{prior}"),
                        f"variant '{v}' not evaluated (no metrics file)") for s in scenes]
        t.rows.append((variant_label(v), cells + [_avg_cell(t, cells)]))
    _bold_best(t, range(len(t.rows)), higher_is_better=False)
    return t


def _weightfree_fmt(key: str) -> str:
    """Significant digits (static leakage is ~1e-6: fixed decimals would print 0.0000); the share of
    still pixels and VBench's flickering score with five decimals (both within 1e-3 of 1)."""
    return "{:.5f}" if key in ("static_outside_mask_still", "vbench/temporal_flickering") else "{:.3g}"


def weightfree_table(records: Sequence[dict[str, Any]]) -> Table:
    """Weight-free metrics of every (scene, method, variant): one row each."""
    cols = [(k, h) for k, h in WEIGHTFREE_COLUMNS if any(k in r["metrics"] for r in records)]
    t = Table("weightfree", "Weight-free motion metrics (static: lower is better; dynamic: motion energy)",
              ["scene", "method"] + [h for _, h in cols])
    for s in _scenes(records):
        start = len(t.rows)
        for r in [r for r in records if r["scene"] == s]:
            v = r.get("variant") or "full"
            label = r["method"] if v == "full" else f"{r['method']} {variant_label(v)}"
            t.rows.append((f"{s} | {label}", [t.cell(r["metrics"].get(k) or
                                                     {"available": False, "reason": f"metric {k!r} not computed"},
                                                     fmt=_weightfree_fmt(k)) for k, _ in cols]))
        recs = [r for r in records if r["scene"] == s]
        for c, (k, _) in enumerate(cols):
            if k.startswith("static_") or k in ("gt/amplitude_w1", "gt/frequency_w1"):  # columns with a "best"
                hib = next((bool(m.get("higher_is_better")) for m in (r["metrics"].get(k) for r in recs)
                            if isinstance(m, dict) and m.get("higher_is_better") is not None), False)
                sub = Table("", "", [])
                sub.rows = [(lbl, [cells[c]]) for lbl, cells in t.rows[start:]]
                _bold_best(sub, range(len(sub.rows)), higher_is_better=hib)
    return t


def build_tables(records: Sequence[dict[str, Any]], ablation_prior: str | None = None) -> list[Table]:
    """All tables for the given metric records (see module doc)."""
    if not records:
        raise ValueError("no metrics records given")
    tables = []
    datasets = list(dict.fromkeys(r.get("dataset", "default") for r in records))
    for i, d in enumerate(datasets):
        sub = [r for r in records if r.get("dataset", "default") == d]
        name = "table1_fvd" if i == 0 else f"table2_fvd_{d}"
        title = "Quantitative evaluation (FVD and FID, lower is better)" + ("" if i == 0 else f" on {d}")
        tables.append(fvd_table(sub, name, title))
    tables.append(multiview_table(records))
    tables.append(ablation_table(records, ablation_prior))
    tables.append(weightfree_table(records))
    if any(FVD_GT in r["metrics"] for r in records):
        tables.append(fvd_gt_table(records))
    return tables


def write_tables(records: Sequence[dict[str, Any]], out_dir: str | Path, ablation_prior: str | None = None) -> list[Path]:
    """Write every table as ``<name>.csv``, ``<name>.md``, ``<name>.tex`` (atomically); return the paths."""
    out = Path(out_dir)
    paths = []
    for t in build_tables(records, ablation_prior):
        for ext, fn in (("csv", to_csv), ("md", to_markdown), ("tex", to_latex)):
            p = out / f"{t.name}.{ext}"
            atomic_write_text(p, fn(t))
            paths.append(p)
    return paths
