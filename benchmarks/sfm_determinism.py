"""Is the sfm stage deterministic? Run it N times on one capture and count distinct ``cameras.json``.

    python benchmarks/sfm_determinism.py CAPTURE --runs 20 --out DIR [--params JSON] [--threads 2] [--keep-work]
        [--contention K] [--pin CPUS]
    python benchmarks/sfm_determinism.py --compare-db RUN_A/work/database.db RUN_B/work/database.db

The first form runs ``anigs --threads T sfm`` (the workflow rule's command; ground truth from
``CAPTURE/gt/cameras.json`` when present) N times, one at a time, into ``DIR/runK`` and prints
per run the md5 of ``cameras.json``, the wall and CPU seconds, the load average and the first step
whose fingerprint (``report.json``, :mod:`anigs.sfm.fingerprint`) differs from run 1's, then the number of
distinct md5s, how many runs gave each, and the median seconds per run. With ``--keep-work``
every run keeps its COLMAP database (``runK/work/database.db``) for the second form.

Under contention: ``--contention K`` keeps K busy processes (pure-Python loops) running through
all runs, and ``--pin CPUS`` (e.g. ``0``) puts the stage and those processes on the same CPUs
(``taskset``-like affinity), so the stage's threads are preempted at arbitrary points: the
schedule a loaded machine gives, on purpose. The load average printed per run includes them.

The second form compares two feature databases of the same photos: keypoints and descriptors
per image, raw matches and two-view geometries (configuration, inlier matches, F/E/H) per pair,
and prints every pair that differs: where two runs diverge.
"""
from __future__ import annotations

import argparse
import collections
import hashlib
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def _pinned(cpus: set[int] | None):
    """A ``preexec_fn`` that restricts the child to ``cpus`` (None: no restriction)."""
    if not cpus:
        return None
    return lambda: os.sched_setaffinity(0, cpus)


def start_contention(k: int, cpus: set[int] | None) -> list[subprocess.Popen]:
    """K busy processes (endless pure-Python loops) on ``cpus``; stop them with :func:`stop_contention`."""
    spin = "x = 0\nwhile True:\n    x = (x * 1103515245 + 12345) % 2147483648\n"
    return [subprocess.Popen([sys.executable, "-c", spin], preexec_fn=_pinned(cpus)) for _ in range(k)]


def stop_contention(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        p.terminate()
    for p in procs:
        p.wait()


def run_once(capture: Path, out: Path, params: str, threads: int, keep_work: bool,
             cpus: set[int] | None = None) -> tuple[str, float, float]:
    from anigs.stages.capture import Outputs as CaptureOutputs
    from anigs.stages.sfm import Outputs as SfmOutputs

    cap = CaptureOutputs(capture)
    cmd = [sys.executable, "-m", "anigs.cli", "--threads", str(threads), "sfm", "--images", str(cap.path("images")),
           "--out", str(out), "--params", params]
    gt = cap.path("gt_cameras")
    if gt.exists():
        cmd += ["--gt-cameras", str(gt)]
    if keep_work:
        cmd.append("--keep-work")
    t0 = time.perf_counter()
    r0 = os.times()
    with open(str(out) + ".log", "w") as log:
        subprocess.run(cmd, check=True, stdout=log, stderr=subprocess.STDOUT, preexec_fn=_pinned(cpus))
    seconds = time.perf_counter() - t0
    r1 = os.times()
    cpu = (r1.children_user - r0.children_user) + (r1.children_system - r0.children_system)
    return hashlib.md5(SfmOutputs(out).path("cameras").read_bytes()).hexdigest(), seconds, cpu


STEPS = ("features", "matches", "mapped", "model")  # report.json's fingerprints, in pipeline order


def first_difference(report: dict, reference: dict) -> str:
    """The first step whose fingerprint (``report.json``) differs from ``reference``'s, or ``same``."""
    a, b = report.get("fingerprints", {}), reference.get("fingerprints", {})
    for step in STEPS:
        if a.get(step) != b.get(step):
            return f"differs from run 1 at {step}" if step in a and step in b else "no fingerprints"
    return "same steps as run 1"


def repeat(args) -> None:
    capture, root = Path(args.capture), Path(args.out)
    root.mkdir(parents=True, exist_ok=True)
    from anigs.stages.sfm import Outputs as SfmOutputs

    cpus = {int(c) for c in args.pin.split(",")} if args.pin else None
    md5s, secs, cpus_s, first = [], [], [], {}
    spinners = start_contention(args.contention, cpus)
    if spinners or cpus:
        print(f"contention: {args.contention} busy process(es), stage and busy processes on CPUs "
              f"{sorted(cpus) if cpus else 'any'}", flush=True)
    try:
        for k in range(1, args.runs + 1):
            out = root / f"run{k}"
            if out.exists():
                shutil.rmtree(out)
            md5, s, c = run_once(capture, out, args.params, args.threads, args.keep_work, cpus)
            md5s.append(md5)
            secs.append(s)
            cpus_s.append(c)
            report = SfmOutputs(out).report()
            first = report if k == 1 else first
            print(f"run {k:2d}  {md5}  {s:6.1f} s  {c:6.1f} CPU s  load {os.getloadavg()[0]:.1f}  "
                  f"{first_difference(report, first)}", flush=True)
    finally:
        stop_contention(spinners)

    counts = collections.Counter(md5s)
    print(f"\n{args.runs} runs, {len(counts)} distinct {SfmOutputs.LAYOUT['cameras'].name}; median {statistics.median(secs):.1f} s per run "
          f"(min {min(secs):.1f}, max {max(secs):.1f}); median {statistics.median(cpus_s):.1f} CPU s per run "
          f"(min {min(cpus_s):.1f}, max {max(cpus_s):.1f})")
    for md5, n in counts.most_common():
        print(f"  {md5}  {n} run(s)")


def _geometries(db) -> dict:
    import pycolmap

    pair_ids, geoms = db.read_two_view_geometries()
    return {pycolmap.pair_id_to_image_pair(p): g for p, g in zip(pair_ids, geoms)}


def compare_databases(a: Path, b: Path) -> int:
    """Print where two databases of the same photos differ; returns the number of differing pairs."""
    import pycolmap

    da, db_ = pycolmap.Database.open(str(a)), pycolmap.Database.open(str(b))
    try:
        ims = {im.image_id: im.name for im in da.read_all_images()}
        same_features = True
        for i, name in sorted(ims.items()):
            ka, kb = np.asarray(da.read_keypoints(i)), np.asarray(db_.read_keypoints(i))
            xa, xb = np.asarray(da.read_descriptors(i).data), np.asarray(db_.read_descriptors(i).data)
            if ka.shape != kb.shape or not np.array_equal(ka, kb) or not np.array_equal(xa, xb):
                same_features = False
                print(f"features differ: image {i} {name}: {len(ka)} vs {len(kb)} keypoints")
        print(f"keypoints and descriptors: {'identical' if same_features else 'DIFFER'} ({len(ims)} images)")
        ga, gb = _geometries(da), _geometries(db_)
        ids = sorted(ims)
        pairs = sorted(set(ga) | set(gb) | {(i, j) for i in ids for j in ids if i < j and
                                           (da.exists_matches(i, j) or db_.exists_matches(i, j))})
        n_match_diff, n_geom_diff = 0, 0
        for p in pairs:
            ma = np.asarray(da.read_matches(*p)) if da.exists_matches(*p) else np.zeros((0, 2))
            mb = np.asarray(db_.read_matches(*p)) if db_.exists_matches(*p) else np.zeros((0, 2))
            raw_same = ma.shape == mb.shape and np.array_equal(ma, mb)
            g1, g2 = ga.get(p), gb.get(p)
            ia = np.asarray(g1.inlier_matches) if g1 is not None else np.zeros((0, 2))
            ib = np.asarray(g2.inlier_matches) if g2 is not None else np.zeros((0, 2))
            geom_same = (g1 is None and g2 is None) or g1 is not None and g2 is not None and g1.config == g2.config and ia.shape == ib.shape \
                and np.array_equal(ia, ib) and np.array_equal(np.asarray(g1.F), np.asarray(g2.F)) \
                and np.array_equal(np.asarray(g1.E), np.asarray(g2.E)) and np.array_equal(np.asarray(g1.H), np.asarray(g2.H))
            n_match_diff += not raw_same
            n_geom_diff += not geom_same
            if not (raw_same and geom_same):
                print(f"pair {ims[p[0]]} - {ims[p[1]]}: raw matches {len(ma)} vs {len(mb)}"
                      f"{'' if raw_same else ' (DIFFER)'}; verified "
                      f"{getattr(g1, 'config', None)} {len(ia)} inliers vs {getattr(g2, 'config', None)} {len(ib)}"
                      f"{'' if geom_same else ' (DIFFER)'}")
        print(f"{len(pairs)} pairs: raw matches differ for {n_match_diff}, two-view geometries for {n_geom_diff}")
        order_a = [pycolmap.pair_id_to_image_pair(p) for p in da.read_two_view_geometries()[0]]
        order_b = [pycolmap.pair_id_to_image_pair(p) for p in db_.read_two_view_geometries()[0]]
        print(f"row order of the two-view geometries: {'same' if order_a == order_b else 'DIFFERS'}")
        return n_geom_diff
    finally:
        da.close()
        db_.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("capture", nargs="?", help="the capture stage's folder (its images, and ground-truth cameras if any)")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--out", default="/tmp/sfm-determinism")
    ap.add_argument("--params", default='{"camera_model": "SIMPLE_PINHOLE", "sift_peak_threshold": 0.004}',
                    help="the sfm section as JSON (default: the demo scene's sfm keys)")
    ap.add_argument("--threads", type=int, default=2, help="anigs --threads (what the workflow rule gives)")
    ap.add_argument("--keep-work", action="store_true", help="keep every run's COLMAP database")
    ap.add_argument("--contention", type=int, default=0, help="busy processes kept running through all runs")
    ap.add_argument("--pin", default="", help="CPUs (comma-separated) for the stage and the busy processes, e.g. 0")
    ap.add_argument("--compare-db", nargs=2, metavar="DB", help="compare two feature databases and exit")
    args = ap.parse_args()
    if args.compare_db:
        compare_databases(Path(args.compare_db[0]), Path(args.compare_db[1]))
        return
    if not args.capture:
        ap.error("CAPTURE is required (or --compare-db)")
    repeat(args)


if __name__ == "__main__":
    main()
