"""Mapping that escalates before it gives up: more pairs, the original photos, a lower initial angle.

When a mapping registers fewer than ``min_registered_fraction`` of the photos, the next step of
the ladder runs (with ``sfm.escalate: true``; each step adds to what the earlier ones matched):

1. ``first``: the matching :func:`anigs.sfm.steps.extract_and_match` ran (``matcher``, ``auto``);
2. ``loops`` (after a sequential matching): loop detection on a vocabulary tree of the capture's
   own descriptors and look-alike pairs (:func:`anigs.sfm.rematch.match_loops`);
3. ``exhaustive`` (after a sequential or spatial matching, at most ``exhaustive_max_images``
   photos): every pair;
4. ``original_resolution``: when the capture was downscaled from photos still on disk, features
   and exhaustive matching on the originals (the model is scaled back to the capture's size);
5. ``lower_angle``: the best step's matches mapped again with ``retry_init_min_tri_angle``
   (when below that step's angle; the only retry with ``escalate: false``);
6. ``restart``: for k = 1, 2, ... (``mapper_restarts`` times at most, stopping at the first that
   registers enough): the best step's matches mapped again with the mapper seeded ``seed + k``, then,
   when that falls short too and those matches are every pair's, the pairs verified again with
   ``seed + k`` (a copy of the database with its keypoints, exhaustive matching whose geometric
   verification RANSACs follow the seed) and mapped with it (step ``reverify``). The incremental
   mapper's choice of initial pair and its RANSACs follow its seed, and so do the verification's: on
   the street capture, seed 1's every rung registered 21 of 29 photos where seeds 0 and 2 reached 27;
   on one machine the mapper's next seed registered 27, on another every mapper seed stayed at 21 or
   fewer, and the pairs verified with seed 2, 3 or 4 registered 27 with any mapper seed (the verified
   pairs are what parts them). A mapping takes seconds, a verification of every pair about as long as
   the exhaustive rung's matching; the seeds follow from the run's, so a run stays deterministic.

Each mapping is an :class:`Attempt` (registered/total, models, seconds) in ``report.json``'s
``mapping.attempts``. The best attempt (most photos registered) is kept. Below
``min_registered_fraction`` but at least ``partial_min_fraction`` of the photos, the run goes on
with the largest model and is marked partial (the photos left out are listed); below that,
:class:`SfmError` names the likely cause and the settings to try (:mod:`anigs.sfm.diagnose`).
"""
from __future__ import annotations

import dataclasses
import logging
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from anigs.photos import import_photos
from anigs.sfm import rematch, steps
from anigs.sfm.config import SfmConfig
from anigs.sfm.diagnose import likely_causes
from anigs.sfm.plan import initial_pair_angle
from anigs.sfm.rematch import database_stats

log = logging.getLogger(__name__)


class SfmError(RuntimeError):
    """Structure from motion did not produce a usable reconstruction."""


@dataclass
class Attempt:
    """One mapping of the ladder and what it gave."""

    step: str  # first | loops | exhaustive | original_resolution | lower_angle | restart | reverify
    matcher: str  # the matching the database holds by then
    resolution: str  # capture | original
    mapper: str
    init_min_tri_angle: Optional[float]
    total: int
    seed: Optional[int] = None  # the mapper's seed (the run's, or the run's + k for a restart / reverify)
    registered: int = 0
    models: list[int] = field(default_factory=list)  # registered photos per model, largest first
    shared_with_largest: list[int] = field(default_factory=list)  # photos each other model shares with the largest
    seconds: float = 0.0  # wall seconds of this step: its added matching and the mapping
    cpu_seconds: float = 0.0
    match_seconds: float = 0.0
    keypoints_per_image: Optional[float] = None
    verified_pairs: Optional[int] = None
    inlier_matches: Optional[int] = None
    result: str = ""

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclass
class Source:
    """A feature database and the image folder it describes (capture size or original)."""

    database: Path
    image_dir: Path
    resolution: str = "capture"
    matcher: str = ""


@dataclass
class Outcome:
    """The escalation's result: the kept model, where it came from, the report entry."""

    rec: Any
    source: Source
    status: str  # complete | partial
    report: dict


def _stats(database: Path) -> dict:
    return database_stats(database) if Path(database).exists() else {}


def _map(src: Source, step: str, work: Path, cfg: SfmConfig, names: list[str], mapper: str,
         angle: float, k: int, match_s: float) -> tuple[Attempt, Any]:
    t0, c0 = time.perf_counter(), steps.cpu_seconds()
    a = Attempt(step, src.matcher, src.resolution, mapper, angle if mapper == "incremental" else None, len(names),
                seed=cfg.seed, match_seconds=match_s, **{k_: v for k_, v in _stats(src.database).items()})
    try:
        models, error = steps.run_mapper(src.database, src.image_dir, work / f"mapping{k}", cfg, names, mapper, angle), None
    except Exception as exc:  # COLMAP raises RuntimeError / ValueError on failures
        models, error = {}, f"{type(exc).__name__}: {exc}"
    chosen, sizes = steps.select_model(models)
    a.models, a.registered = sizes, (sizes[0] if sizes else 0)
    a.shared_with_largest = shared_images(models, chosen)
    a.seconds = match_s + time.perf_counter() - t0
    a.cpu_seconds = steps.cpu_seconds() - c0
    a.result = error or ("no model" if not sizes else f"registered {a.registered}/{len(names)}")
    log.info("sfm attempt %d (%s: %s matches, %s resolution, init_min_tri_angle=%s, seed %d): %s, models %s, %.1f s",
             k + 1, step, a.matcher, a.resolution, a.init_min_tri_angle, cfg.seed, a.result, sizes, a.seconds)
    return a, chosen


def shared_images(models: dict, largest) -> list[int]:
    """Registered photos each other model shares with ``largest`` (a merge needs 3 or more to place a model;
    pycolmap 4.2 binds no model merger, so none is attempted)."""
    if largest is None:
        return []
    names = {largest.images[i].name for i in largest.reg_image_ids()}
    others = sorted((r for r in models.values() if r is not largest), key=lambda r: r.num_reg_images(), reverse=True)
    return [len(names & {r.images[i].name for i in r.reg_image_ids()}) for r in others]


def _angle(src: Source, cfg: SfmConfig) -> tuple[float, Optional[dict]]:
    if cfg.init_min_tri_angle != "auto":
        return float(cfg.init_min_tri_angle), None
    if cfg.mapper != "incremental":
        return 16.0, None
    return initial_pair_angle(src.database)


def map_escalating(first: Source, work: Path, cfg: SfmConfig, names: list[str], device=None,
                   originals: Optional[Path] = None, mode: Optional[str] = None) -> Outcome:
    """Run the ladder of the module docstring from the database ``first`` (already matched).

    ``originals``: folder of the full-size photos of a downscaled capture (same names), or None.
    Raises :class:`SfmError` (cause and settings) when the best model holds fewer than
    ``partial_min_fraction`` of the photos.
    """
    total = len(names)
    need = cfg.min_registered_fraction * total
    tried: list[Attempt] = []
    kept: dict[int, tuple[Any, Source]] = {}  # only the best model is held
    best_k = -1

    def run(src: Source, step: str, mapper: str, angle: float, match_s: float = 0.0, seed_offset: int = 0) -> bool:
        nonlocal best_k
        seeded = dataclasses.replace(cfg, seed=cfg.seed + seed_offset) if seed_offset else cfg
        a, chosen = _map(src, step, work, seeded, names, mapper, angle, len(tried), match_s)
        tried.append(a)
        if chosen is not None and (best_k < 0 or a.registered > tried[best_k].registered):
            kept.clear()
            kept[len(tried) - 1] = (chosen, src)
            best_k = len(tried) - 1
        return chosen is not None and a.registered >= need

    angle, auto_info = _angle(first, cfg)
    done = run(first, "first", cfg.mapper, angle)
    if not done and cfg.escalate:
        if first.matcher == "sequential" and first.database.exists():
            log.warning("sfm: %s; adding loop and look-alike pairs", tried[-1].result)
            info = rematch.match_loops(first.database, first.image_dir, names, cfg, device, work)
            first.matcher = "sequential+loops"
            done = run(first, "loops", cfg.mapper, _angle(first, cfg)[0], info["match_s"])
        if not done and first.matcher in ("sequential+loops", "spatial") and first.database.exists() \
                and total <= cfg.exhaustive_max_images:
            log.warning("sfm: %s; matching every pair", tried[-1].result)
            info = rematch.match_every_pair(first.database, cfg, device)
            first.matcher = "exhaustive"
            done = run(first, "exhaustive", cfg.mapper, _angle(first, cfg)[0], info["match_s"])
        if not done and originals is not None:
            log.warning("sfm: %s; trying the photos at their original resolution (%s)", tried[-1].result, originals)
            t0 = time.perf_counter()
            orig = original_source(originals, names, work, cfg, mode)
            done = run(orig, "original_resolution", cfg.mapper, _angle(orig, cfg)[0], time.perf_counter() - t0)
    retry = cfg.retry_init_min_tri_angle
    if not done and retry is not None:
        base, base_attempt = (kept[best_k][1], tried[best_k]) if best_k >= 0 else (first, tried[0])
        if base_attempt.mapper != "incremental" or retry < (base_attempt.init_min_tri_angle or 90.0):
            log.warning("retrying mapping with init_min_tri_angle=%g degrees (was %s)", retry, tried[-1].result)
            done = run(base, "lower_angle", "incremental", retry)
    if not done and cfg.escalate and cfg.mapper_restarts and best_k >= 0:
        done = restart(tried[best_k], kept[best_k][1], cfg, run, work, device)

    report: dict[str, Any] = {"attempts": [a.as_dict() for a in tried], "retries": len(tried) - 1,
                              "init_min_tri_angle_auto": auto_info, "escalate": cfg.escalate}
    best = tried[best_k] if best_k >= 0 else None
    reg = best.registered if best else 0
    report["best_attempt"] = best_k if best_k >= 0 else None
    if best is None or reg < min(need, cfg.partial_min_fraction * total):
        raise SfmError(failure_message(reg, total, cfg, tried, kept, first))
    rec, src = kept[best_k]
    registered = sorted(rec.images[i].name for i in rec.reg_image_ids())
    status = "complete" if reg >= need else "partial"
    report.update(models_found=best.models, other_models=best.models[1:], status=status)
    if len(best.models) > 1:
        log.warning("mapping produced %d models with %s registered images; keeping the largest (%d/%d)",
                    len(best.models), best.models, reg, total)
    if status == "partial":
        left_out = sorted(set(names) - set(registered))
        log.warning("sfm: PARTIAL reconstruction: the best model registers %d/%d photos (below "
                    "min_registered_fraction=%g, at least partial_min_fraction=%g); continuing with it. "
                    "Photos left out (%d): %s", reg, total, cfg.min_registered_fraction, cfg.partial_min_fraction,
                    len(left_out), ", ".join(left_out))
    return Outcome(rec, src, status, report)


def restart(best: Attempt, src: Source, cfg: SfmConfig, run, work: Path, device=None) -> bool:
    """Rung ``restart`` (module docstring): the best attempt's matches, mapper and angle, mapped again with the
    seeds after the run's, each followed (every pair's matches only) by the pairs verified again with that seed and
    mapped with it, until one registers enough; whether one did."""
    log.warning("sfm: the best mapping registers %d/%d photos; mapping the same matches again with %d other "
                "mapper seeds (sfm.mapper_restarts)%s", best.registered, best.total, cfg.mapper_restarts,
                ", each followed by every pair verified again with that seed" if src.matcher == "exhaustive" else "")
    angle = best.init_min_tri_angle if best.init_min_tri_angle is not None else _angle(src, cfg)[0]  # global: unused
    for k in range(1, cfg.mapper_restarts + 1):
        if run(src, "restart", best.mapper, angle, seed_offset=k):
            return True
        if src.matcher == "exhaustive":
            again, match_s = reverified(src, work / f"reverify{k}", dataclasses.replace(cfg, seed=cfg.seed + k), device)
            if run(again, "reverify", best.mapper, angle, match_s, seed_offset=k):
                return True
    return False


def reverified(src: Source, folder: Path, cfg: SfmConfig, device=None) -> tuple[Source, float]:
    """A copy of ``src``'s database in ``folder`` with its keypoints and descriptors, every pair matched and
    verified again under ``cfg.seed`` (the verification's RANSACs follow it) on ``device`` (None: the config's);
    (its source, the matching's wall s)."""
    import pycolmap

    folder.mkdir(parents=True, exist_ok=True)
    db = folder / "database.db"
    shutil.copyfile(src.database, db)
    copy = pycolmap.Database.open(str(db))
    try:
        copy.clear_matches()
        copy.clear_two_view_geometries()
    finally:
        copy.close()
    info = rematch.match_every_pair(db, cfg, device if device is not None else steps.colmap_device(cfg))
    return Source(db, src.image_dir, src.resolution, "exhaustive"), info["match_s"]


def failure_message(reg: int, total: int, cfg: SfmConfig, tried: list[Attempt], kept: dict, first: Source) -> str:
    """The below-``partial_min_fraction`` error: attempts, likely cause, settings to try."""
    rec_src = next(iter(kept.values()), (None, first))
    rec, src = rec_src
    registered = sorted(rec.images[i].name for i in rec.reg_image_ids()) if rec is not None else []
    causes, settings, _ = likely_causes(src.database, [a.as_dict() for a in tried], registered, cfg.single_camera)
    detail = "; ".join(f"attempt {k + 1} ({a.step}: {a.matcher}, {a.resolution} resolution, init_min_tri_angle="
                       f"{a.init_min_tri_angle}): {a.result} (models {a.models})" for k, a in enumerate(tried))
    return (f"structure from motion registered {reg}/{total} images, below min_registered_fraction="
            f"{cfg.min_registered_fraction} (need {int(np.ceil(cfg.min_registered_fraction * total))}) and below "
            f"partial_min_fraction={cfg.partial_min_fraction} (a partial run needs "
            f"{int(np.ceil(cfg.partial_min_fraction * total))}). Likely cause: {'; '.join(causes)}. "
            f"Settings to try: {'; '.join(settings)}. Attempts: {detail}")


def original_source(originals: Path, names: list[str], work: Path, cfg: SfmConfig, mode: Optional[str]) -> Source:
    """Import the full-size photos (upright, as PNG, same names) and extract and match them exhaustively."""
    folder = work / "original" / "images"
    written = set(import_photos(originals, folder, None, skip_unreadable=True, screen=False))
    missing = sorted(set(names) - written)
    if missing:
        raise FileNotFoundError(f"original photos in {originals} lack {len(missing)} capture image(s): {missing[:5]}")
    for extra in sorted(written - set(names)):
        (folder / extra).unlink()
    db = work / "original" / "database.db"
    n = len(names)
    matcher = "exhaustive" if n <= cfg.exhaustive_max_images else "sequential"
    steps.extract_and_match(db, folder, names, dataclasses.replace(cfg, matcher=matcher), mode)
    return Source(db, folder, "original", matcher)


def rescale_model(rec, sizes: dict[str, tuple[int, int]]) -> dict:
    """Scale a model of the original photos to the capture's image sizes (cameras and 2D points)."""
    scales = {}
    for cam_id, cam in rec.cameras.items():
        name = next(rec.images[i].name for i in rec.reg_image_ids() if rec.images[i].camera_id == cam_id)
        w, h = sizes[name]
        scales[cam_id] = (w / cam.width, h / cam.height)
        cam.rescale(w, h)
        rec.cameras[cam_id] = cam
    for i in rec.reg_image_ids():
        im = rec.images[i]
        sx, sy = scales[im.camera_id]
        for p in im.points2D:
            p.xy = np.array([p.xy[0] * sx, p.xy[1] * sy])
    return {str(k): list(v) for k, v in scales.items()}
