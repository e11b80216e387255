"""The COLMAP steps of :func:`anigs.sfm.colmap.run_sfm`: SIFT extraction and matching into a
database, one mapping run, the choice among the models it returns and their fine-scale refinement.

Tests replace :func:`extract_and_match` and :func:`run_mapper` on :mod:`anigs.sfm.colmap` (which
re-exports them; :mod:`anigs.sfm.escalate` calls them through it). ``cfg.num_threads`` must be a
count (:func:`anigs.sfm.colmap.resolve_config`).
"""
from __future__ import annotations

import logging
import resource
import time
from pathlib import Path
from typing import Any

from anigs.photos import image_headers, list_images
from anigs.sfm.bundle import refine_fine_scale
from anigs.sfm.config import SfmConfig
from anigs.sfm.plan import choose_matcher, similar_pairs
from anigs.sfm.rematch import matching_kwargs

log = logging.getLogger("anigs.sfm.colmap")


def cpu_seconds() -> float:
    """CPU seconds (user + system) of this process, all threads."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def colmap_device(cfg: SfmConfig):
    import pycolmap

    has_cuda = bool(pycolmap.has_cuda)
    if cfg.device.startswith("cuda") and not has_cuda:  # the run's device: torch's stages use the GPU, SIFT cannot
        log.warning("device is %r but this pycolmap build has no CUDA support: SIFT runs on the CPU (a CUDA build of "
                    "pycolmap runs it on the GPU)", cfg.device)
    return pycolmap.Device.cuda if (cfg.device != "cpu" and has_cuda) else pycolmap.Device.cpu


def camera_mode(cfg: SfmConfig, sizes: list[tuple[int, int]]) -> str:
    """COLMAP camera mode for images of ``sizes`` (distinct (width, height)): ``SINGLE`` for one
    shared camera, ``AUTO`` (one camera per size) when the sizes differ only by a 90-degree turn
    (portrait and landscape photos of one camera), ``PER_IMAGE`` with ``single_camera: false``;
    any other mix of sizes is an error naming them."""
    if not cfg.single_camera:
        return "PER_IMAGE"
    if len(sizes) <= 1:
        return "SINGLE"
    if len(sizes) == 2 and sizes[0] == sizes[1][::-1]:
        log.info("sfm: portrait and landscape photos (%dx%d and %dx%d): one camera per orientation",
                 *sizes[0], *sizes[1])
        return "AUTO"
    raise ValueError(f"sfm.single_camera is true but the images have {len(sizes)} sizes {sizes[:5]} that are "
                     "not one size turned by 90 degrees; set single_camera to false or import them at one size")


def extract_and_match(database: Path, image_dir: Path, names: list[str], cfg: SfmConfig,
                      mode: str | None = None) -> dict:
    """SIFT extraction and matching into ``database`` (``mode``: a :func:`camera_mode`); returns
    statistics and timings (wall ``*_s``, CPU ``*_cpu_s``), the matcher run and why
    (``matcher: auto`` is chosen here, from the keypoints found: :func:`anigs.sfm.plan.choose_matcher`).
    ``cfg.num_threads`` must be a count (:func:`resolve_config`)."""
    import pycolmap

    if cfg.num_threads < 1 or cfg.matching_num_threads < 1:
        raise ValueError("extract_and_match needs thread counts (sfm.colmap.resolve_config)")
    device = colmap_device(cfg)
    pycolmap.set_random_seed(cfg.seed)
    reader = pycolmap.ImageReaderOptions(camera_model=cfg.camera_model)
    if cfg.camera_params is not None:
        reader.camera_params = ",".join(str(float(v)) for v in cfg.camera_params)
    ext = pycolmap.FeatureExtractionOptions()
    ext.num_threads = cfg.num_threads
    ext.max_image_size = cfg.max_image_size
    ext.sift.max_num_features = cfg.max_num_features
    ext.sift.peak_threshold = cfg.sift_peak_threshold
    ext.use_gpu = device == pycolmap.Device.cuda
    mode = getattr(pycolmap.CameraMode, mode or ("SINGLE" if cfg.single_camera else "PER_IMAGE"))
    t0, c0 = time.perf_counter(), cpu_seconds()
    # images enter the database first, one thread, in name order: several extraction threads would
    # otherwise number them in the order they finish, and the mapper's choices follow the numbers
    pycolmap.Database.open(str(database)).close()
    pycolmap.import_images(database, image_dir, camera_mode=mode, image_names=names, options=reader)
    pycolmap.extract_features(database, image_dir, image_names=names, camera_mode=mode,
                              reader_options=reader, extraction_options=ext, device=device)
    t1, c1 = time.perf_counter(), cpu_seconds()
    db = pycolmap.Database.open(database)
    try:
        keypoints_per_image = db.num_keypoints() / max(db.num_images(), 1)
    finally:
        db.close()
    matcher, why = choose_matcher(cfg.matcher, [Path(image_dir) / n for n in names], cfg.exhaustive_max_images,
                                  cfg.exhaustive_max_comparisons, keypoints_per_image)
    if cfg.matcher == "auto":
        log.info("sfm: matcher %s (%s)", matcher, why["reason"])
    kw = matching_kwargs(cfg, device)
    extra_pairs = 0
    if matcher == "exhaustive":
        pycolmap.match_exhaustive(database, **kw)
    elif matcher == "sequential":
        pairing = pycolmap.SequentialPairingOptions()
        pairing.overlap = cfg.sequential_overlap
        pairing.quadratic_overlap = True
        pairing.num_threads = cfg.num_threads
        pycolmap.match_sequential(database, pairing_options=pairing, **kw)
        extra = similar_pairs([Path(image_dir) / n for n in names], cfg.sequential_similar, cfg.sequential_overlap)
        if extra:
            pairs_file = Path(database).with_name("similar_pairs.txt")
            pairs_file.write_text("".join(f"{names[i]} {names[j]}\n" for i, j in extra))
            imported = pycolmap.ImportedPairingOptions()
            imported.match_list_path = str(pairs_file)
            pycolmap.match_image_pairs(database, pairing_options=imported, **kw)
        extra_pairs = len(extra)
    else:
        db = pycolmap.Database.open(database)
        try:
            n_priors = db.num_pose_priors()
        finally:
            db.close()
        if n_priors == 0:
            raise ValueError("sfm.matcher 'spatial' needs location priors (EXIF GPS), but none of the "
                             f"{len(names)} images has one; use 'sequential' or 'exhaustive'")
        pairing = pycolmap.SpatialPairingOptions()
        pairing.max_num_neighbors = cfg.spatial_max_neighbors
        pycolmap.match_spatial(database, pairing_options=pairing, **kw)
    t2, c2 = time.perf_counter(), cpu_seconds()
    db = pycolmap.Database.open(database)
    try:
        stats = {"keypoints_per_image": db.num_keypoints() / max(db.num_images(), 1),
                 "verified_pairs": db.num_verified_image_pairs(), "inlier_matches": db.num_inlier_matches()}
    finally:
        db.close()
    stats.update(extract_s=t1 - t0, match_s=t2 - t1, extract_cpu_s=c1 - c0, match_cpu_s=c2 - c1,
                 device=str(device).split(".")[-1], matcher=matcher, matcher_choice=why, similar_pairs=extra_pairs)
    return stats


def run_mapper(database: Path, image_dir: Path, out_dir: Path, cfg: SfmConfig, names: list[str],
               mapper: str, init_min_tri_angle: float) -> dict:
    """One COLMAP mapping run -> ``{model index: pycolmap.Reconstruction}`` (may be empty)."""
    import pycolmap

    pycolmap.set_random_seed(cfg.seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    if mapper == "global":
        opts = pycolmap.GlobalPipelineOptions()
        opts.random_seed = cfg.seed
        opts.num_threads = cfg.mapper_num_threads
        opts.min_model_size = 3
        opts.image_names = names
        cuda = colmap_device(cfg) == pycolmap.Device.cuda
        opts.mapper.global_positioning.use_gpu = cuda
        opts.mapper.bundle_adjustment.ceres.use_gpu = cuda
        return dict(pycolmap.global_mapping(database, image_dir, out_dir, options=opts))
    opts = pycolmap.IncrementalPipelineOptions()
    opts.random_seed = cfg.seed
    opts.num_threads = cfg.mapper_num_threads
    opts.min_model_size = 3
    opts.image_names = names
    opts.ba_global_frames_ratio = opts.ba_global_points_ratio = float(cfg.ba_global_growth)
    opts.ba_global_max_refinements = int(cfg.ba_global_max_refinements)
    opts.ba_local_max_refinements = int(cfg.ba_local_max_refinements)
    opts.ba_refine_extra_params = not cfg.mapper_holds_distortion()
    opts.mapper.init_min_tri_angle = float(init_min_tri_angle)
    opts.mapper.random_seed = cfg.seed
    opts.triangulation.random_seed = cfg.seed
    return dict(pycolmap.incremental_mapping(database, image_dir, out_dir, options=opts))


# ---- model selection -----------------------------------------------------------------------

def select_model(models: dict) -> tuple[Any, list[int]]:
    """Pick the model with most registered images; returns it and all models' sizes (descending)."""
    if not models:
        return None, []
    ranked = sorted(models.values(), key=lambda r: r.num_reg_images(), reverse=True)
    return ranked[0], [int(r.num_reg_images()) for r in ranked]


# ---- refinement ------------------------------------------------------------------------------

def refine_model(rec, database: Path, cfg: SfmConfig) -> dict:
    """Fine-scale refinement of the mapped model in place (:mod:`anigs.sfm.bundle`); returns its report.

    Skipped (with the reason in the report) when ``cfg.refine`` is off or the database with
    the keypoints is missing or does not match the model.
    """
    if not cfg.refine:
        return {"applied": False, "reason": "sfm.refine is false"}
    if not database.exists():
        return {"applied": False, "reason": "no feature database (model not mapped here)"}
    try:
        report = refine_fine_scale(rec, database, max_keypoint_scale=cfg.refine_max_keypoint_scale,
                                   min_observations=cfg.refine_min_observations, loss_scale=cfg.refine_loss_scale,
                                   num_threads=cfg.mapper_num_threads, max_image_size=cfg.max_image_size,
                                   max_iterations=cfg.refine_max_iterations)
    except ValueError as exc:
        log.warning("fine-scale refinement skipped: %s", exc)
        return {"applied": False, "reason": str(exc)}
    return {"applied": True, **report}


def larger_originals(originals: str | Path | None, headers: dict) -> Path | None:
    """``originals`` when it holds a larger photo (after EXIF rotation) for every capture image, else None."""
    if originals is None or not Path(originals).is_dir():
        return None
    by_stem = {p.stem: p for p in list_images(originals)}
    stems = {Path(n).stem: wh for n, wh in headers.items()}
    if not set(stems) <= set(by_stem):
        return None
    orig = image_headers([by_stem[s] for s in stems])
    for s, (w, h, _) in stems.items():
        ow, oh, o = orig[by_stem[s].name]
        if o in (5, 6, 7, 8):
            ow, oh = oh, ow
        if max(ow, oh) <= max(w, h):
            return None
    return Path(originals)


