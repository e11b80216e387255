"""Benchmark the sfm stage on a capture folder and print its figures.

    python benchmarks/sfm.py CAPTURE [--before | --before-and-after] [--repeats N] [--compare-to DIR] [--out DIR] [--params JSON]

CAPTURE is a capture folder with ``images/`` (and, for the synthetic demo, ``gt/cameras.json``)
or a plain folder of photos (``/work/shared/captures/flower-llff``). With ground truth the
reconstruction is aligned to it (similarity on the camera centres) and the pose errors are
printed. Prints registered/total, points and track lengths, reprojection error, what the
fine-scale refinement kept, what ``auto`` chose, and wall and CPU seconds per step (plan,
extract, match, mapping, refine, undistort, total) with the load average: on a shared machine
wall seconds include contention, CPU seconds (all threads of the process) much less so.

``--before`` runs the settings the stage had before it chose them from the capture
(exhaustive matching, one thread, initial-pair angle 16 degrees, COLMAP's bundle-adjustment
schedule); ``--params`` overrides either. ``--compare-to DIR`` (an earlier output folder, e.g.
of ``--before --out DIR``) reports how far the cameras are from that run's after a similarity
alignment on the centres: rotation differences in degrees and centre differences in percent of
the largest distance between two reference centres. ``--repeats N`` runs N times and prints
the median seconds (the figures of the last run). ``--before-and-after`` does both runs (into
OUT/before and OUT/after) and prints them side by side. Examples:

    python benchmarks/sfm.py /work/shared/captures/flower-llff --before-and-after --out /tmp/sfm-bench
    python benchmarks/sfm.py /work/shared/captures/flower-llff --before --out /tmp/sfm-bench/before
    python benchmarks/sfm.py /work/shared/captures/flower-llff --compare-to /tmp/sfm-bench/before --repeats 3
    python benchmarks/sfm.py results/demo/capture --params '{"camera_model": "SIMPLE_PINHOLE", "refine": false}'
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

# the stage's settings before it chose them from the capture (and the demo scene's own keys stay)
BEFORE = {"matcher": "exhaustive", "num_threads": 1, "mapper_num_threads": 1, "init_min_tri_angle": 16.0,
          "ba_global_growth": 1.1, "ba_global_max_refinements": 5, "ba_local_max_refinements": 2}


def pose_agreement(cams, ref_cams) -> dict:
    """Rotation (degrees) and centre (percent of the reference extent) differences of ``cams``
    from ``ref_cams`` (matched by name) after the similarity that best maps the centres."""
    from anigs.sfm.align import rotation_angle_deg, umeyama

    ref = {c.name: c for c in ref_cams}
    pairs = [(c, ref[c.name]) for c in cams if c.name in ref]
    if len(pairs) < 3:
        return {"cameras": len(pairs)}
    a = np.stack([c.center for c, _ in pairs])
    b = np.stack([r.center for _, r in pairs])
    sim = umeyama(a, b)
    rot = np.array([rotation_angle_deg(c.R @ sim.R.T, r.R) for c, r in pairs])
    extent = float(np.max(np.linalg.norm(b[:, None] - b[None], axis=-1)))
    cen = 100 * np.linalg.norm(sim.apply(a) - b, axis=1) / max(extent, 1e-12)
    focal = np.array([100 * abs(c.K[0, 0] / r.K[0, 0] - 1) for c, r in pairs])
    return {"cameras": len(pairs), "rotation_deg": {"mean": float(rot.mean()), "max": float(rot.max())},
            "center_pct_extent": {"mean": float(cen.mean()), "max": float(cen.max())},
            "focal_pct": float(focal.max())}


def bench(capture: Path, out: Path, params: dict, label: str, repeats: int = 1, compare_to: str | None = None,
          threads: int | None = None) -> dict:
    """Run the stage ``repeats`` times with ``params`` into ``out``, print its figures, return them."""
    from anigs.sfm.colmap import SfmConfig, run_sfm
    from anigs.stages import capture as capture_stage, sfm as sfm_stage

    cap, sfm_out = capture_stage.Outputs(capture), sfm_stage.Outputs(out)
    images = cap.path("images") if cap.path("images").is_dir() else capture
    gt = cap.path("gt_cameras")
    cfg = SfmConfig.from_dict(params)
    load_start = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    runs = []
    for _ in range(max(1, repeats)):
        res = run_sfm(images, sfm_out, cfg, gt_cameras=gt if gt.exists() else None, threads=threads)
        runs.append(res.report)
    r = runs[-1]
    wall = {k: statistics.median(x["timings_s"][k] for x in runs) for k in r["timings_s"]}
    cpu = {k: statistics.median(x["cpu_s"][k] for x in runs) for k in r["cpu_s"]}
    with np.load(sfm_out.path("points")) as pts:
        track = pts["track_length"]
    auto = r.get("auto", {})
    figures = {
        "capture": str(capture), "settings": label, "params": params,
        "matcher": auto.get("matcher", cfg.matcher), "mapper": cfg.mapper,
        "num_threads": auto.get("num_threads"), "mapper_num_threads": auto.get("mapper_num_threads"),
        "init_min_tri_angle": [a["init_min_tri_angle"] for a in r["mapping"]["attempts"]],
        "registered": r["registered"], "images": r["images"], "num_points": r["num_points"],
        "track_length": {"mean": float(track.mean()), "median": float(np.median(track))} if len(track) else None,
        "verified_pairs": r.get("features", {}).get("verified_pairs"),
        "keypoints_per_image": r.get("features", {}).get("keypoints_per_image"),
        "retries": r["mapping"]["retries"], "models_found": r["mapping"]["models_found"],
        "mean_reprojection_error_px": r["mean_reprojection_error_px"],
        "repeats": len(runs), "seconds": wall, "cpu_seconds": cpu,
        "load_average": [load_start, list(os.getloadavg())] if load_start else None,
        "refine": r.get("refine", {}), "output": str(out),
    }
    print(f"capture            {capture}  ({cfg.camera_model}, {figures['matcher']} matching "
          f"[{(auto.get('matcher_choice') or {}).get('reason', 'set')}], {cfg.mapper} mapping, {label} settings)")
    print(f"threads            extract/match/undistort {figures['num_threads']}, mapper/BA {figures['mapper_num_threads']}; "
          f"initial-pair angle {figures['init_min_tri_angle']} deg")
    print(f"registered         {r['registered']}/{r['images']}  (models found: {r['mapping']['models_found']}, "
          f"retries: {r['mapping']['retries']})")
    for k, a in enumerate(r["mapping"]["attempts"]):
        print(f"  attempt {k + 1:<10} {a.get('step', '?')}: {a.get('matcher', '')} matches, "
              f"{a.get('resolution', 'capture')} resolution, angle {a['init_min_tri_angle']}: {a['result']} "
              f"(models {a['models']}), {a['seconds']:.1f} s")
    if r.get("status") == "partial":
        print(f"PARTIAL            left out: {', '.join(r['unregistered_images'])}")
    if figures["keypoints_per_image"] is not None:
        print(f"features           {figures['keypoints_per_image']:.0f} keypoints per image, "
              f"{figures['verified_pairs']} verified pairs")
    tl = figures["track_length"] or {"mean": 0, "median": 0}
    print(f"sparse points      {r['num_points']}  (mean reprojection error {r['mean_reprojection_error_px']:.3f} px; "
          f"track length mean {tl['mean']:.2f}, median {tl['median']:.0f})")
    ref = r.get("refine", {})
    if ref.get("applied"):
        print(f"refinement         kept {ref['observations_kept']}/{ref['observations_total']} observations "
              f"(points {ref['points_kept']}/{ref['points_total']}, fewest per image {ref['min_observations_per_image']}), "
              f"Cauchy scale {ref['cauchy_loss_scale_px'] or 0:.3f} px; reprojection error "
              f"{ref['mean_reprojection_error_before_px']:.3f} -> {ref['mean_reprojection_error_after_px']:.3f} px")
    else:
        print(f"refinement         not applied ({ref.get('reason', 'no report')})")
    if "gt_errors" in r:
        e = r["gt_errors"]
        figures["gt_errors"] = {k: e[k] for k in ("rotation_error_deg", "rotation_error_deg_after_best_rotation",
                                                  "center_error_pct_extent", "focal_error_pct", "extent")}
        print(f"rotation error     mean {e['rotation_error_deg']['mean']:.3f}  max {e['rotation_error_deg']['max']:.3f} deg "
              f"(after best rotation: max {e['rotation_error_deg_after_best_rotation']['max']:.3f})")
        print(f"centre error       mean {e['center_error_pct_extent']['mean']:.3f}%  "
              f"max {e['center_error_pct_extent']['max']:.3f}% of extent ({e['extent']:.2f} world units)")
        print(f"focal error        {e['focal_error_pct']['max']:.3f}%")
    else:
        print(f"rotation/centre    no ground truth ({capture_stage.Outputs.LAYOUT['gt_cameras'].name}) in the capture folder")
    if compare_to:
        agree = pose_agreement(sfm_out.cameras(), sfm_stage.Outputs(compare_to).cameras())
        figures["agreement"] = {"reference": str(compare_to), **agree}
        if "rotation_deg" in agree:
            print(f"vs reference       {agree['cameras']} cameras: rotation mean {agree['rotation_deg']['mean']:.3f} "
                  f"max {agree['rotation_deg']['max']:.3f} deg; centre mean {agree['center_pct_extent']['mean']:.3f}% "
                  f"max {agree['center_pct_extent']['max']:.3f}% of extent; focal {agree['focal_pct']:.2f}% "
                  f"({compare_to})")
        else:
            print(f"vs reference       only {agree['cameras']} cameras in common with {compare_to}")
    rep = f" (median of {len(runs)})" if len(runs) > 1 else ""
    print(f"wall seconds{rep} " + "  ".join(f"{k} {v:.1f}" for k, v in wall.items()))
    print(f"CPU seconds{rep}  " + "  ".join(f"{k} {v:.1f}" for k, v in cpu.items() if v is not None))
    if figures["load_average"]:
        la = figures["load_average"]
        print("load average       " + " ".join(f"{x:.2f}" for x in la[0]) + " at the start, "
              + " ".join(f"{x:.2f}" for x in la[1]) + f" at the end ({os.cpu_count()} CPUs)")
    print(f"output             {out}")
    return figures


def side_by_side(before: dict, after: dict) -> None:
    """The two runs' main figures in two columns."""
    def row(name, f):
        print(f"{name:<28}{f(before):>14}{f(after):>14}")

    print(f"\n{'':<28}{'before':>14}{'after':>14}")
    row("matcher", lambda x: x["matcher"])
    row("registered", lambda x: f"{x['registered']}/{x['images']}")
    row("verified pairs", lambda x: str(x["verified_pairs"]))
    row("sparse points", lambda x: str(x["num_points"]))
    row("track length mean/median", lambda x: "{mean:.2f}/{median:.0f}".format(**(x["track_length"] or {"mean": 0, "median": 0})))
    row("reprojection error (px)", lambda x: f"{x['mean_reprojection_error_px']:.3f}")
    for k in after["seconds"]:
        row(f"wall s {k}", lambda x, k=k: f"{x['seconds'].get(k, float('nan')):.1f}")
    for k in after["cpu_seconds"]:
        row(f"CPU s {k}", lambda x, k=k: f"{(x['cpu_seconds'].get(k) or float('nan')):.1f}")
    if "gt_errors" in after:
        row("rotation error max (deg)", lambda x: f"{x['gt_errors']['rotation_error_deg']['max']:.3f}")
        row("centre error max (% ext.)", lambda x: f"{x['gt_errors']['center_error_pct_extent']['max']:.3f}")
    a = after.get("agreement", {})
    if "rotation_deg" in a:
        print(f"after vs before: rotation mean {a['rotation_deg']['mean']:.3f} max {a['rotation_deg']['max']:.3f} deg, "
              f"centre mean {a['center_pct_extent']['mean']:.3f}% max {a['center_pct_extent']['max']:.3f}% of extent, "
              f"focal {a['focal_pct']:.2f}% (similarity-aligned on the centres)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("capture", help="capture folder (the capture stage's: images, maybe ground-truth cameras), or a folder of photos")
    ap.add_argument("--out", default=None, help="output folder (default: a temporary folder)")
    ap.add_argument("--params", default=None, help="sfm config section as JSON or @file (on top of --before)")
    ap.add_argument("--before", action="store_true", help="the settings before the stage chose them from the capture")
    ap.add_argument("--before-and-after", action="store_true",
                    help="run --before into OUT/before, then the current settings into OUT/after compared with it")
    ap.add_argument("--repeats", type=int, default=1, help="runs; the seconds printed are medians")
    ap.add_argument("--compare-to", default=None, help="an earlier sfm output folder: camera agreement with it")
    ap.add_argument("--threads", type=int, default=None, help="what num_threads -1 means (like anigs --threads)")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON line too")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    from anigs.cli import parse_params

    capture = Path(args.capture)
    extra = parse_params(args.params) or {}
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="anigs_sfm_bench."))
    if args.before_and_after:
        before = bench(capture, out / "before", {**BEFORE, **extra}, "before", args.repeats, args.compare_to, args.threads)
        print()
        after = bench(capture, out / "after", dict(extra), "current", args.repeats, str(out / "before"), args.threads)
        side_by_side(before, after)
        results = [before, after]
    else:
        params = {**BEFORE, **extra} if args.before else dict(extra)
        results = [bench(capture, out, params, "before" if args.before else "current", args.repeats, args.compare_to,
                         args.threads)]
    if args.json:
        for f in results:
            print(json.dumps(f, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
