"""Which seed parts a stalled mapping: the mapper's, or the pairs' verification? (rung ``reverify``, issue 48)

    python benchmarks/sfm_verify_seeds.py --images CACHE/seed-1/lund-street/capture/images --seed 1 \
        --verify-seeds 2 3 4 [--work DIR] [--angle 4]

Extracts the photos' SIFT features once and matches every pair under ``--seed`` (as the sfm stage's
exhaustive rung does), maps that database with the mapper seeded ``--seed``; then, per ``--verify-seeds`` V,
a copy of the database with its matches and two-view geometries cleared is matched and verified again under
V (:func:`anigs.sfm.escalate.reverified`) and mapped with mapper seed ``--seed`` and with V. Prints the photos
each mapping registers and the matching's seconds: when the run's own verification stalls the mapping whatever
the mapper's seed, and another verification seed does not, the rung ``reverify`` is what helps.
"""
from __future__ import annotations

import argparse
import dataclasses
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from anigs.sfm import steps
    from anigs.sfm.colmap import resolve_config
    from anigs.sfm.config import SfmConfig
    from anigs.sfm.escalate import Source, reverified

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--verify-seeds", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--angle", type=float, default=4.0, help="the mapper's init_min_tri_angle (degrees)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", type=Path, default=None, help="kept when given (default: a temporary folder)")
    a = ap.parse_args()
    work = a.work or Path(tempfile.mkdtemp(prefix="sfm_verify_seeds_"))
    work.mkdir(parents=True, exist_ok=True)
    names = sorted(p.name for p in a.images.iterdir() if not p.name.startswith("."))
    cfg, _ = resolve_config(SfmConfig.from_dict({"seed": a.seed, "matcher": "exhaustive"}), a.threads)
    db = work / "database.db"
    t0 = time.perf_counter()
    steps.extract_and_match(db, a.images, names, cfg)
    print(f"{len(names)} photos; features and every pair matched under seed {a.seed} in "
          f"{time.perf_counter() - t0:.0f} s")

    def registered(database: Path, seed: int, tag: str) -> int:
        models = steps.run_mapper(database, a.images, work / f"map-{tag}", dataclasses.replace(cfg, seed=seed),
                                  names, "incremental", a.angle)
        return steps.select_model(models)[1][0] if models else 0

    print(f"| verification seed | mapper seed {a.seed} | its own mapper seed | matching s |\n|---|---|---|---|")
    print(f"| {a.seed} (the run's) | {registered(db, a.seed, 'run')}/{len(names)} | - | - |", flush=True)
    src = Source(db, a.images, "capture", "exhaustive")
    for v in a.verify_seeds:
        again, match_s = reverified(src, work / f"verify{v}", dataclasses.replace(cfg, seed=v))
        print(f"| {v} | {registered(again.database, a.seed, f'{v}-run')}/{len(names)} | "
              f"{registered(again.database, v, f'{v}-own')}/{len(names)} | {match_s:.0f} |", flush=True)
    if a.work is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
