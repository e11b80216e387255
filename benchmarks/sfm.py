"""Benchmark the sfm stage on a capture folder and print its figures.

    python benchmarks/sfm.py results/demo/capture [--out DIR] [--params '{"camera_model": "SIMPLE_PINHOLE"}']

The capture folder holds ``images/`` and, for the synthetic demo, ``gt/cameras.json``; with
ground truth the reconstruction is aligned to it (similarity on the camera centres) and the
pose errors are printed. Prints registered/total, rotation and centre errors, point count,
what the fine-scale refinement kept, and wall seconds per step (extract, match, mapping,
refine, undistort, total; on a shared machine these include contention). Compare with the
refinement off: ``--params '{"camera_model": "SIMPLE_PINHOLE", "refine": false}'``.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("capture", help="capture folder with images/ (and gt/cameras.json)")
    ap.add_argument("--out", default=None, help="output folder (default: a temporary folder)")
    ap.add_argument("--params", default=None, help="sfm config section as JSON or @file")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON line too")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    from anigs.cli import parse_params
    from anigs.sfm.colmap import SfmConfig, run_sfm

    capture = Path(args.capture)
    images = capture / "images"
    gt = capture / "gt" / "cameras.json"
    cfg = SfmConfig.from_dict(parse_params(args.params))
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="anigs_sfm_bench."))
    res = run_sfm(images, out, cfg, gt_cameras=gt if gt.exists() else None)
    r = res.report
    figures = {
        "capture": str(capture), "camera_model": cfg.camera_model, "matcher": cfg.matcher, "mapper": cfg.mapper,
        "registered": r["registered"], "images": r["images"], "num_points": r["num_points"],
        "retries": r["mapping"]["retries"], "models_found": r["mapping"]["models_found"],
        "mean_reprojection_error_px": round(r["mean_reprojection_error_px"], 3),
        "seconds": {k: round(v, 2) for k, v in r["timings_s"].items()},
        "refine": {k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.get("refine", {}).items()},
    }
    print(f"capture            {capture}  ({cfg.camera_model}, {cfg.matcher} matching, {cfg.mapper} mapping)")
    print(f"registered         {r['registered']}/{r['images']}  (models found: {r['mapping']['models_found']}, "
          f"retries: {r['mapping']['retries']})")
    print(f"sparse points      {r['num_points']}  (mean reprojection error {r['mean_reprojection_error_px']:.3f} px)")
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
        print("rotation/centre    no ground truth (gt/cameras.json) in the capture folder")
    t = r["timings_s"]
    print("seconds            " + "  ".join(f"{k} {v:.1f}" for k, v in t.items()))
    print(f"output             {out}")
    if args.json:
        print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
