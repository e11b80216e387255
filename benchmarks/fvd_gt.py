"""FVD-GT of every variant of a scene, with its spread, clip counts and where the time went.

    python benchmarks/fvd_gt.py results/demo [--json OUT]

Reads ``results/{scene}/fvd_gt/reference.json`` (the ground truth's views and features, and the
no-motion control) and ``results/{scene}/{variant}/eval/fvd_gt.json`` (each variant's record, as
``snakemake tables`` writes them) and prints one line per variant: FVD-GT, the bootstrap std and
central interval, clips per side, views, and the seconds spent rendering the evaluation views,
running I3D on them and computing the distances (the reference's line: the ground truth's).
Seconds per I3D clip are the feature seconds over the clips.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from anigs.stages.fvd_gt import Outputs, ReferenceOutputs  # noqa: E402


def _records(scene_dir: Path) -> list[Outputs]:
    """The variants' FVD-GT folders of a scene (those with a record)."""
    return [o for o in (Outputs(p / "eval") for p in sorted(scene_dir.iterdir()) if p.is_dir()) if o.exists("record")]


def rows(scene_dir: Path) -> list[dict]:
    out = []
    refs = ReferenceOutputs(scene_dir / "fvd_gt")
    if refs.exists("reference"):
        ref = refs.json("reference")
        secs = ref.get("seconds") or {}
        out.append({"run": "ground truth (reference)", "value": None, "clips": ref.get("clips"),
                    "views": ref.get("views"), "render_s": secs.get("render"), "features_s": secs.get("features"),
                    "total_s": ref.get("seconds_total"), "gt_vbench": ref.get("gt_vbench")})
        still = ref.get("still_control")
        if still:
            out.append(_line("static scene, no motion (control)", still, still.get("seconds") or {}))
    for o in _records(scene_dir):
        rec = o.json("record")
        m = rec["metrics"]["fvd/gt"]
        label = rec["method"] if rec.get("variant", "full") == "full" else f"{rec['method']} {rec['variant']}"
        out.append(_line(label, m, m.get("seconds") or {}, rec.get("seconds")))
    return out


def _line(label: str, m: dict, secs: dict, total=None) -> dict:
    if not m.get("available"):
        return {"run": label, "value": None, "reason": m.get("reason")}
    b = m.get("bootstrap") or {}
    s = m.get("samples") or {}
    return {"run": label, "value": m["value"], "std": b.get("std"), "interval": b.get("interval"),
            "clips": s.get("test"), "reference_clips": s.get("reference"), "views": s.get("views"),
            "render_s": secs.get("render"), "features_s": secs.get("features"),
            "frechet_s": (m.get("protocol") or {}).get("frechet_seconds"), "total_s": total}


def _f(x, fmt=".2f"):
    return "" if x is None else format(x, fmt)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene_dir", type=Path, help="results/{scene}")
    ap.add_argument("--json", type=Path, help="also write the rows as JSON")
    args = ap.parse_args()
    table = rows(args.scene_dir)
    if not table:
        print(f"no FVD-GT records under {args.scene_dir} (run `snakemake tables`)")
        return 1
    print("| run | FVD-GT | bootstrap std | 90% interval | clips (GT) | views | render s | I3D s | s per clip | FD+bootstrap s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in table:
        iv = r.get("interval")
        per = r["features_s"] / r["clips"] if r.get("features_s") and r.get("clips") else None
        print(f"| {r['run']} | {_f(r.get('value')) or 'n/a ' + str(r.get('reason') or '')} | {_f(r.get('std'))} | "
              f"{'' if not iv else f'{iv[0]:.2f} - {iv[1]:.2f}'} | {r.get('clips') or ''}"
              f"{' (' + str(r['reference_clips']) + ')' if r.get('reference_clips') else ''} | {r.get('views') or ''} | "
              f"{_f(r.get('render_s'), '.1f')} | {_f(r.get('features_s'), '.1f')} | {_f(per)} | {_f(r.get('frechet_s'), '.1f')} |")
    gt = next((r.get("gt_vbench") for r in table if r.get("gt_vbench")), None)
    if gt:
        print(f"\nground truth's own VBench figures on the evaluation views: flickering {gt['temporal_flickering']:.5f}, "
              f"dynamic-degree proxy {gt['dynamic_degree_proxy']:.2f}")
    gaps = paired_gaps(args.scene_dir)
    if gaps:
        print("\nPaired gaps (the same bootstrap draws of views for both; an interval that excludes 0 is a real gap):")
        print("| A - B | mean | std | 90% interval |")
        print("|---|---|---|---|")
        for g in gaps:
            print(f"| {g['pair']} | {g['mean']:.2f} | {g['std']:.2f} | {g['interval'][0]:.2f} - {g['interval'][1]:.2f} |")
    if args.json:
        args.json.write_text(json.dumps({"rows": table, "gaps": gaps}, indent=1))
    return 0


def paired_gaps(scene_dir: Path) -> list[dict]:
    """FD(A, GT) - FD(B, GT) over the same bootstrap draws for every pair of the full model, the
    no-motion control and the other variants (from the saved features)."""
    import numpy as np

    from anigs.metrics.bootstrap import bootstrap_gap

    refs = ReferenceOutputs(scene_dir / "fvd_gt")
    if not refs.exists("features"):
        return []
    cfg = refs.json("reference")["config"]
    with np.load(refs.path("features")) as z:
        f_gt, views = z["features"], z["views"]
    sets = {}
    if refs.exists("still_features"):
        with np.load(refs.path("still_features")) as z:
            sets["no motion"] = z["features"]
    for o in _records(scene_dir):
        if not o.exists("features"):
            continue
        p = o.path("features")
        rec = o.json("record")
        label = rec["method"] if rec.get("variant", "full") == "full" else f"{rec['method']} {rec['variant']}"
        with np.load(p) as z:
            if z["features"].shape != f_gt.shape:  # made against another reference: not paired
                print(f"(skipped {p}: {z['features'].shape[0]} clips against the reference's {f_gt.shape[0]})")
                continue
            sets[label] = z["features"]
    order = [k for k in ("Ours", "no motion") if k in sets] + [k for k in sets if k not in ("Ours", "no motion")]
    out = []
    for i, base in enumerate(order):  # every pair once: later minus earlier
        for name in order[i + 1:]:
            g = bootstrap_gap(sets[name], sets[base], f_gt, views, cfg["bootstrap"], cfg["seed"], cfg["level"])
            out.append({"pair": f"{name} - {base}", **g.to_dict()})
    return out


if __name__ == "__main__":
    raise SystemExit(main())
