"""Run a photo scene through the workflow and print what a real capture gives at each stage.

    python benchmarks/photo_scene.py --photos ../shared/captures/flower-llff [--cores 1]
        [--results /tmp/photo-bench/results] [--scene photos] [--variant full]
        [--config KEY=VALUE ...] [--no-run] [--sheet PNG] [--json]

Runs ``snakemake`` from the repository root with ``ANIGS_PHOTOS=--photos`` (the scene file
``config/scenes/photos.yaml`` reads its folder from it), ``scenes=[--scene]`` and
``results=--results``, up to the variant's evaluation (``eval/metrics.json``: the static fit,
effects, views, masks, every round and the final clips; not the export or the viewer). Snakemake
skips what is up to date, so a second call only reports. ``--no-run`` reports on what is there.

Prints, each from the file that records it:

- registered / total photos: ``sfm/report.json`` (``registered``, ``images``) and the photo folder;
- held-out PSNR of the static fit: ``static/metrics.json`` (``test_psnr`` over ``test_views``);
- queued views with coverage >= ``--min-coverage``: ``views/views.json`` (each view's ``coverage``);
- per-effect fractions: ``effects/effects.json`` (share of the analysed photos' pixels per
  effect, and which were chosen) and ``masks/masks.json`` (share of each queued view's pixels in
  the dynamic mask and in each effect's mask, mean over views);
- outside-mask stillness: ``{variant}/eval/metrics.json`` ``static_outside_mask_still`` (mean over
  views and the worst view);
- seconds per stage: Snakemake's benchmark TSVs (column ``s``, and ``cpu_time``), summed over a
  stage's jobs: ``{scene}/benchmarks/*.tsv`` and ``{scene}/{variant}/benchmarks/**/*.tsv`` (a
  round folder's TSVs from an earlier run are left out, see :func:`stage_seconds`).

Writes a contact sheet (:mod:`anigs.metrics.contact`; default ``{results}/{scene}/{variant}/
contact_sheet.png``): per view the first frame of the final clip, its masks, and a heat map of
``max |I_t - I_0|`` with the outline of the mask dilated as eval's stillness metric dilates it.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from anigs.stages.eval import Outputs as EvalOutputs  # noqa: E402
from anigs.stages.final import Outputs as FinalOutputs  # noqa: E402
from anigs.stages.masks import Outputs as MasksOutputs  # noqa: E402

PHOTO_EXT = (".jpg", ".jpeg", ".png")


def read_json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.exists() else None


def stage_json(scene_dir: Path, stage: str, key: str) -> dict | None:
    """A scene stage's JSON file ``key`` (its ``Outputs``), None when the stage has not run."""
    import importlib

    out = importlib.import_module(f"anigs.stages.{stage}").Outputs(scene_dir / stage)
    return out.json(key) if out.exists(key) else None


def _snakemake(args, scene_dir: Path, variant_dir: Path, *extra: str) -> tuple[list[str], dict]:
    """The snakemake command line up to the variant's eval, and its environment."""
    from anigs.stages.effects import Outputs as EffectsOutputs

    exe = Path(sys.executable).with_name("snakemake")
    cmd = [str(exe) if exe.exists() else "snakemake", "--cores", str(args.cores), *extra,
           *(["--configfile", str(Path(args.configfile).resolve())] if args.configfile else []),
           "--config", f'scenes=["{args.scene}"]', f"results={args.results}", *args.config,
           "--", str(EvalOutputs(variant_dir / "eval").path("metrics")), str(EffectsOutputs(scene_dir / "effects").path("effects"))]
    env = {**os.environ}
    if args.photos:
        env["ANIGS_PHOTOS"] = str(Path(args.photos).resolve())
    return cmd, env


def run_workflow(args, scene_dir: Path, variant_dir: Path) -> float:
    """snakemake up to the variant's eval; returns the wall seconds."""
    cmd, env = _snakemake(args, scene_dir, variant_dir, "--rerun-incomplete")
    print(f"$ ANIGS_PHOTOS={env['ANIGS_PHOTOS']} {' '.join(cmd)}", flush=True)
    t0 = time.perf_counter()
    res = subprocess.run(cmd, cwd=ROOT, env=env, check=False)
    if res.returncode:
        raise SystemExit(f"snakemake failed (exit {res.returncode}); see the logs under {scene_dir}/logs "
                         f"and {variant_dir}/logs")
    return time.perf_counter() - t0


def stage_seconds(scene_dir: Path, variant: str) -> tuple[dict[str, dict[str, float]], list[str]]:
    """(stage -> {jobs, s, cpu_s} summed over the benchmark TSVs, the TSVs left out as stale).

    Per-view jobs ``NAME_vNN`` are one stage. A results folder reused across layouts of the
    workflow (per-view render/refine jobs, later one job per round) keeps the old layout's TSVs,
    which are left out: every job of round R reads the model of round R-1 (round 1: the view
    queue), so a TSV in ``roundR/`` older than that ``update.tsv`` (``views.tsv``) is stale, and
    so is one older than a stale TSV of a later round (that run had gone past round R)."""
    bench, vbench = scene_dir / "benchmarks", scene_dir / variant / "benchmarks"
    rounds: dict[int, list[Path]] = defaultdict(list)
    for d in vbench.glob("round*"):
        m = re.fullmatch(r"round(\d+)", d.name)
        if m and d.is_dir():
            rounds[int(m.group(1))] = sorted(d.glob("*.tsv"))
    stale: list[Path] = []
    later_stale = -math.inf
    for r in sorted(rounds, reverse=True):
        up = vbench / f"round{r - 1}" / "update.tsv" if r > 1 else bench / "views.tsv"
        bound = max(up.stat().st_mtime if up.exists() else -math.inf, later_stale)
        old = [f for f in rounds[r] if f.stat().st_mtime < bound]
        stale += old
        later_stale = max([later_stale, *(f.stat().st_mtime for f in old)])
    files = sorted(bench.glob("*.tsv")) + sorted(vbench.rglob("*.tsv"))
    out: dict[str, dict[str, float]] = defaultdict(lambda: {"jobs": 0, "s": 0.0, "cpu_s": 0.0})
    for f in files:
        if f in stale:
            continue
        stage = re.sub(r"_v\d+$", "", f.stem)
        with open(f) as fh:
            for rec in csv.DictReader(fh, delimiter="\t"):
                out[stage]["jobs"] += 1
                out[stage]["s"] += float(rec["s"])
                try:
                    out[stage]["cpu_s"] += float(rec.get("cpu_time") or "nan")
                except ValueError:
                    out[stage]["cpu_s"] = math.nan
    return dict(out), sorted(str(f.relative_to(scene_dir)) for f in stale)


def figures(args, scene_dir: Path, variant_dir: Path) -> dict:
    fig: dict = {"scene": args.scene, "variant": args.variant, "results": str(args.results)}
    photos = Path(args.photos) if args.photos else None
    n_folder = sum(1 for p in photos.iterdir() if p.suffix.lower() in PHOTO_EXT) if photos and photos.is_dir() else None
    rep = stage_json(scene_dir, "sfm", "report")
    if rep:
        fig["sfm"] = {"registered": rep["registered"], "images": rep["images"], "photos_in_folder": n_folder,
                      "unregistered": rep.get("unregistered_images", []), "points": rep.get("num_points"),
                      "reprojection_px": rep.get("mean_reprojection_error_px")}
    st = stage_json(scene_dir, "static", "metrics")
    if st:
        fig["static"] = {k: st.get(k) for k in ("test_psnr", "test_ssim", "test_views", "train_psnr", "train_views",
                                                 "num_gaussians", "iterations")}
    vj = stage_json(scene_dir, "views", "views")
    if vj:
        cov = [v.get("coverage") for v in vj["views"]]
        fig["views"] = {"queued": len(cov), "min_coverage": args.min_coverage,
                        "covered": sum(1 for c in cov if c is not None and c >= args.min_coverage),
                        "coverage": {v["id"]: c for v, c in zip(vj["views"], cov)},
                        "layout": (vj.get("layout") or {}).get("kind", (vj.get("layout") or {}).get("layout")),
                        "rejected": len((vj.get("scene_coverage") or {}).get("rejected", []))}
    ej = stage_json(scene_dir, "effects", "effects")
    if ej:
        fig["effects"] = {"detected": ej.get("detected"), "chosen": ej.get("chosen"),
                          "dynamic_gaussian_fraction": ej.get("dynamic_fraction"),
                          "pixel_fraction": {e: r["pixel_fraction"] for e, r in ej["effects"].items()},
                          "gaussian_fraction": {e: r["gaussian_fraction"] for e, r in ej["effects"].items()}}
    mj = stage_json(scene_dir, "masks", "report")
    if mj and mj.get("views"):
        vs = mj["views"]
        effs = sorted({e for v in vs for e in v.get("effects", {})})
        fig["masks"] = {"views": len(vs), "dynamic_mean": sum(v["fraction"] for v in vs) / len(vs),
                        "dynamic_per_view": {v["id"]: v["fraction"] for v in vs},
                        "effect_mean": {e: sum(v.get("effects", {}).get(e, 0.0) for v in vs) / len(vs) for e in effs}}
    ev = read_json(EvalOutputs(variant_dir / "eval").path("metrics"))
    if ev:
        rec = ev["metrics"].get("static_outside_mask_still")
        if rec is None:
            fig["still"] = {"available": False, "reason": f"not in {EvalOutputs.LAYOUT['metrics'].name} (an older eval)"}
        elif not rec.get("available"):
            fig["still"] = {"available": False, "reason": rec.get("reason")}
        else:
            pv = rec.get("per_view") or {}
            worst = min(pv, key=pv.get) if pv else None
            fig["still"] = {"available": True, "mean": rec["value"], "worst_view": worst,
                            "worst": pv.get(worst) if worst else None, "per_view": pv}
    fig["seconds"], fig["stale_tsvs"] = stage_seconds(scene_dir, args.variant)
    return fig


def contact(args, variant_dir: Path, scene_dir: Path, fig: dict) -> None:
    from anigs.metrics.contact import load_rows, save_contact_sheet
    from anigs.metrics.config import EvalConfig

    clips = FinalOutputs(variant_dir / "final").path("clips")
    if not clips.is_dir():
        print(f"contact sheet: no final clips in {clips}")
        return
    ev = read_json(EvalOutputs(variant_dir / "eval").path("metrics")) or {}
    cfg = {**EvalConfig().__dict__, **(ev.get("config") or {})}  # eval's margin, tolerance and threshold
    rows = load_rows(clips, MasksOutputs(scene_dir / "masks"), threshold=cfg["mask_threshold"])
    sheet = Path(args.sheet) if args.sheet else variant_dir / "contact_sheet.png"
    stats = save_contact_sheet(sheet, rows, margin_px=cfg["still_margin_px"], tolerance=cfg["still_tolerance"])
    fig["contact_sheet"] = {"path": str(sheet), "rows": stats}


def _f(x, fmt=".3f") -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def report(fig: dict) -> None:
    print(f"\n== photo scene {fig['scene']} ({fig['variant']}), results in {fig['results']}")
    s = fig.get("sfm")
    if s:
        print(f"registered photos: {s['registered']}/{s['images']} (photo folder: {s['photos_in_folder']}); "
              f"{s['points']} points, mean reprojection error {_f(s['reprojection_px'], '.2f')} px"
              + (f"; unregistered: {', '.join(s['unregistered'])}" if s["unregistered"] else ""))
    s = fig.get("static")
    if s:
        print(f"static fit: held-out PSNR {_f(s['test_psnr'], '.2f')} dB (SSIM {_f(s['test_ssim'])}) over "
              f"{s['test_views']} held-out photos; train PSNR {_f(s['train_psnr'], '.2f')} dB over {s['train_views']}; "
              f"{s['num_gaussians']} Gaussians, {s['iterations']} iterations")
    s = fig.get("views")
    if s:
        cov = " ".join(f"{v}:{_f(c, '.2f')}" for v, c in s["coverage"].items())
        print(f"views: {s['covered']} of {s['queued']} queued views have coverage >= {s['min_coverage']} "
              f"(layout {s['layout']}, {s['rejected']} directions rejected); {cov}")
    s = fig.get("effects")
    if s:
        print(f"effects: detected {s['detected']}, chosen {s['chosen']}; dynamic Gaussians "
              f"{100 * (s['dynamic_gaussian_fraction'] or 0):.1f}%")
        for e, pf in s["pixel_fraction"].items():
            print(f"  {e:14s} photo pixels {100 * pf:5.1f}%   Gaussians {100 * s['gaussian_fraction'][e]:5.1f}%")
    s = fig.get("masks")
    if s:
        print(f"masks ({s['views']} views): dynamic {100 * s['dynamic_mean']:.1f}% of the pixels (mean); "
              + ", ".join(f"{e} {100 * v:.1f}%" for e, v in s["effect_mean"].items()))
        print("  per view: " + " ".join(f"{v}:{100 * f:.1f}%" for v, f in s["dynamic_per_view"].items()))
    s = fig.get("still")
    if s:
        if s["available"]:
            print(f"static_outside_mask_still: mean {_f(s['mean'])}, worst {s['worst_view']} {_f(s['worst'])}; "
                  + " ".join(f"{v}:{_f(x)}" for v, x in s["per_view"].items()))
        else:
            print(f"static_outside_mask_still: not available ({s['reason']})")
    sec = fig.get("seconds") or {}
    if sec:
        print("seconds per stage (Snakemake benchmark TSVs, summed over a stage's jobs):")
        for st, r in sec.items():
            print(f"  {st:14s} {r['jobs']:3d} job(s) {r['s']:9.1f} s wall {r['cpu_s']:9.1f} s CPU")
        print(f"  {'total':14s} {sum(r['jobs'] for r in sec.values()):3d} job(s) "
              f"{sum(r['s'] for r in sec.values()):9.1f} s wall {sum(r['cpu_s'] for r in sec.values()):9.1f} s CPU")
    if fig.get("stale_tsvs"):
        print(f"  (left out as stale, from an earlier run: {len(fig['stale_tsvs'])} TSV(s), e.g. "
              f"{', '.join(fig['stale_tsvs'][:3])})")
    c = fig.get("contact_sheet")
    if c:
        print(f"contact sheet: {c['path']}")
        for r in c["rows"]:
            if "mask_fraction" in r:
                print(f"  {r['view']}: mask {100 * r['mask_fraction']:.1f}%, mask pixels moving "
                      f"{100 * r['mask_moving']:.0f}%, still outside {_f(r['outside_still'])}, "
                      f"largest change outside {_f(r['outside_max_change'])}")
            else:
                print(f"  {r['view']}: no mask; largest change {_f(r['max_change'])}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", default=None, help="folder of the photos (becomes ANIGS_PHOTOS; needed unless --no-run)")
    ap.add_argument("--scene", default="photos", help="scene file in config/scenes whose photos: is ${ANIGS_PHOTOS}")
    ap.add_argument("--results", type=Path, default=Path("/tmp/photo-bench/results"), help="workflow results folder")
    ap.add_argument("--variant", default="full")
    ap.add_argument("--cores", default="1", help="snakemake --cores")
    ap.add_argument("--configfile", default=None, help="a preset on top of the defaults, e.g. config/quality.yaml")
    ap.add_argument("--config", nargs="*", default=[], metavar="KEY=VALUE", help="more snakemake --config entries")
    ap.add_argument("--min-coverage", type=float, default=0.8, help="coverage a queued view counts from")
    ap.add_argument("--no-run", action="store_true", help="report on the results that are there")
    ap.add_argument("--sheet", default=None, help="contact sheet PNG (default {results}/{scene}/{variant}/contact_sheet.png)")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON line too")
    args = ap.parse_args(argv)
    if args.photos is None and not args.no_run:
        ap.error("--photos is needed to run the workflow (or report on existing results with --no-run)")
    args.results = args.results.resolve()
    scene_dir = args.results / args.scene
    variant_dir = scene_dir / args.variant
    wall = None if args.no_run else run_workflow(args, scene_dir, variant_dir)
    fig = figures(args, scene_dir, variant_dir)
    if wall is not None:
        fig["workflow_wall_s"] = wall
    contact(args, variant_dir, scene_dir, fig)
    report(fig)
    if wall is not None:
        print(f"this call's snakemake: {wall:.1f} s wall")
    if args.json:
        print(json.dumps(fig, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
