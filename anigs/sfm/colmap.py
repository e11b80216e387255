"""Structure from motion with pycolmap 4.x: images -> cameras + sparse points.

Pipeline (:func:`run_sfm`): check the images (unreadable files, fewer than 3) before COLMAP
runs -> thread counts -> SIFT extraction (GPU when available) -> matching: exhaustive, sequential
or spatial, ``auto`` choosing from the photos' order and the keypoint count
(:mod:`anigs.sfm.plan`) -> the initial-pair angle from the matches (``init_min_tri_angle: auto``)
-> incremental mapping (or global mapping) with the failure handling below (for
SIMPLE_RADIAL/RADIAL the mapper holds the distortion at its start, zero unless given:
``mapper_refine_distortion``) ->
fine-scale refinement (:mod:`anigs.sfm.bundle`: bundle adjustment of the cameras on the finest,
best-localised keypoints, robust loss; every point is kept; it also estimates the distortion the
mapper held, which one plain bundle adjustment does with refine off) -> undistortion to PINHOLE
when the camera model has distortion -> frame normalisation -> outputs.

Parameters live in :mod:`anigs.sfm.config`, model conversion in :mod:`anigs.sfm.model`.

Reproducibility: extraction (the images enter the database in name order first, so several
threads cannot renumber them) and undistortion gave bit-identical databases, cameras and images
for 1, 2 and 4 threads (tests/sfm; the 34-photo flower capture; the demo), so they use
``num_threads`` (all available CPUs by default). Matching runs on ``matching_num_threads`` (1 by
default): every RANSAC is seeded per pair (``seed``), but COLMAP's CPU matcher builds a FAISS index
per image in each matching thread, and one run of the demo's matching with 4 threads gave other
raw matches for 2 of 1128 pairs (both with one image); one thread takes the same CPU seconds. The
mapper and the bundle adjustments are
bit-identical for a seed only with ``mapper_num_threads: 1`` (the default; 2 threads changed the
cameras in the last digits from run to run). The report has wall and CPU seconds per step
(``timings_s``, ``cpu_s``: CPU seconds of all the process's threads, less sensitive than wall
seconds to other work on a shared machine), what ``auto`` chose (``auto``, ``mapping``) and a digest
after each step (``fingerprints``: :mod:`anigs.sfm.fingerprint`), which names the step where two runs
of the same photos part.

Failure handling (:mod:`anigs.sfm.escalate`): several models: the one with most registered images
is kept, the others are reported; a mapping that registers fewer than ``min_registered_fraction``
of the images escalates (loop and look-alike pairs, every pair, the original photos of a
downscaled capture, a lower initial angle), then continues partial with the largest model
(``status: partial``, the photos left out in ``unregistered_images``) when it holds at least
``partial_min_fraction``, or fails naming the likely cause and the settings to try.

Frame normalisation (downstream works in a z-up world, ground near z=0): without ground
truth, up is estimated from the cameras held upright (:func:`anigs.geometry.estimate_up`) and rotated onto
+z; the camera centroid moves to x=y=0, a low percentile of the point heights to z=0, and
the scale makes the mean camera height ``camera_height`` (eye height: roughly metric). With ground-truth cameras the reconstruction is instead mapped onto
them with a similarity (Umeyama on camera centres) and the pose errors are reported.

Output folder (laid out like a COLMAP project, so 3DGS tools open it directly):
the sfm stage's ``Outputs`` (:mod:`anigs.stages.sfm`) name its files: ``sparse`` (``0/``: COLMAP
binary model in the output frame, PINHOLE cameras after undistortion), ``images`` (the images the
cameras describe: undistorted, or copies), ``cameras`` (project convention, one camera per
registered image, ``name`` = file name), ``points`` (``xyz`` [P,3] float32, ``rgb`` [P,3] float32
in [0,1], ``error`` [P] float32 reprojection error in px, ``track_length`` [P] int32), ``tracks``
(per image, the points it observes: :mod:`anigs.sfm.tracks`), ``report``,
``work`` (kept with ``keep_work``).
"""
from __future__ import annotations

import dataclasses
import logging
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from anigs.sfm.align import pose_errors, umeyama, upright_similarity
from anigs.cameras import Camera, load_cameras, save_cameras
from anigs.io import StageFolder, write_json, write_npz
from anigs.photos import check_images, image_headers, list_images, report_unreadable, require_min_images
from anigs.sfm.config import MAPPERS, MATCHERS, UNDISTORTED_MODELS, SfmConfig
from anigs.sfm.escalate import Source, SfmError, map_escalating, rescale_model
from anigs.sfm.model import (find_model_dir, reconstruction_cameras, reconstruction_points, replace_dir,
                             to_sim3d)
from anigs.sfm.bundle import adjust_intrinsics
from anigs.sfm.fingerprint import database_fingerprints, model_fingerprint
from anigs.sfm import steps
from anigs.sfm.tracks import model_tracks, save_tracks
from anigs.sfm.plan import resolve_threads
from anigs.sfm.steps import camera_mode, colmap_device, cpu_seconds, larger_originals, refine_model, select_model

# COLMAP's extraction, matching and mapping are called through their module (steps.extract_and_match,
# steps.run_mapper: here and in anigs.sfm.escalate), so a test replaces them there, once, for both
__all__ = ["MAPPERS", "MATCHERS", "UNDISTORTED_MODELS", "SfmConfig", "SfmError", "SfmResult", "camera_mode",
           "cpu_seconds", "larger_originals", "reconstruction_cameras", "reconstruction_points",
           "refine_model", "resolve_config", "run_sfm", "select_model"]

log = logging.getLogger(__name__)


@dataclass
class SfmResult:
    """What :func:`run_sfm` produced (also written to its ``out``)."""

    cameras: list[Camera]
    xyz: np.ndarray  # [P,3] float32
    rgb: np.ndarray  # [P,3] float32 in [0,1]
    report: dict = field(default_factory=dict)


def resolve_config(cfg: SfmConfig, cli_threads: int | None = None) -> tuple[SfmConfig, dict]:
    """``cfg`` with the thread counts resolved (:func:`anigs.sfm.plan.resolve_threads`).

    ``matcher: auto`` needs the keypoint count (:func:`anigs.sfm.steps.extract_and_match` resolves it) and
    ``init_min_tri_angle: auto`` the matches (:func:`anigs.sfm.escalate.map_escalating`). Returns the config and
    the report entry.
    """
    threads = resolve_threads(cfg.num_threads, cli_threads)
    matching_threads = threads if cfg.matching_num_threads == -1 else cfg.matching_num_threads
    mapper_threads = threads if cfg.mapper_num_threads == -1 else cfg.mapper_num_threads
    return (dataclasses.replace(cfg, num_threads=threads, matching_num_threads=matching_threads,
                                mapper_num_threads=mapper_threads),
            {"num_threads": threads, "matching_num_threads": matching_threads, "mapper_num_threads": mapper_threads})


# ---- the stage -----------------------------------------------------------------------------------

def run_sfm(image_dir: str | Path, out: StageFolder, cfg: SfmConfig | None = None,
            gt_cameras: str | Path | None = None, model_dir: str | Path | None = None,
            keep_work: bool = False, threads: int | None = None, originals: str | Path | None = None) -> SfmResult:
    """Run the whole stage; see the module docstring for steps, failures and outputs.

    Args:
        image_dir: folder of JPEG/PNG images.
        out: the sfm stage's folder (:class:`anigs.stages.sfm.Outputs`; created): where each file goes.
        cfg: parameters (defaults when None).
        gt_cameras: ground-truth cameras JSON (synthetic capture): align to them and report errors.
        model_dir: an existing COLMAP sparse model of these images: skips extraction, matching
            and mapping (registration is still checked against the images in ``image_dir``).
        keep_work: keep the COLMAP database and raw models in ``out``'s ``work`` folder.
        threads: ``anigs --threads`` (what Snakemake gives the job): the count ``num_threads: -1`` means.
        originals: folder of the photos ``image_dir`` was downscaled from (same stems): the
            escalation's ``original_resolution`` step (:mod:`anigs.sfm.escalate`) uses them.
    """
    import pycolmap

    cfg = cfg or SfmConfig()
    t_start, c_start = time.perf_counter(), cpu_seconds()
    image_dir, out_dir = Path(image_dir), Path(out.root)
    names, bad, headers, mode = _check_capture(image_dir, cfg, model_dir)
    total = len(names)
    gt = load_cameras(gt_cameras) if gt_cameras else None

    out_dir.mkdir(parents=True, exist_ok=True)
    work = out.path("work") if keep_work else Path(tempfile.mkdtemp(prefix=".sfm_work.", dir=out_dir))
    if keep_work and work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {"images": total, "skipped_unreadable": bad, "config": dataclasses.asdict(cfg),
                              "pycolmap_version": pycolmap.__version__, "timings_s": {}, "cpu_s": {}}
    cfg, report["auto"] = resolve_config(cfg, threads)
    try:
        if model_dir is not None:
            rec = _existing_model(Path(model_dir), image_dir, names, headers, cfg, report)
        else:
            rec = _map(work, image_dir, names, cfg, mode, headers, originals, report)
        report["registered"] = int(rec.num_reg_images())
        report["registered_fraction"] = report["registered"] / total
        registered = sorted(rec.images[i].name for i in rec.reg_image_ids())
        report["unregistered_images"] = sorted(set(names) - set(registered))
        report["partial"] = report["status"] == "partial"
        rec, images_tmp = _undistort(rec, work, out_dir, image_dir, registered, cfg, report)
        cams, pts = _normalise_frame(rec, gt, gt_cameras, cfg, report)

        # outputs: folders built under temporary names and renamed; files written atomically
        sparse_tmp = Path(tempfile.mkdtemp(prefix=".sparse.", dir=out_dir))
        (sparse_tmp / "0").mkdir()
        rec.write(sparse_tmp / "0")
        replace_dir(sparse_tmp, out.path("sparse"))
        replace_dir(images_tmp, out.path("images"))
        save_cameras(out.path("cameras"), cams, extra={"source": "colmap", "frame": report["frame"]["mode"]})
        write_npz(out.path("points"), **pts)
        save_tracks(out.path("tracks"), model_tracks(rec))
        report["timings_s"]["total"], report["cpu_s"]["total"] = time.perf_counter() - t_start, cpu_seconds() - c_start
        report["load_average"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
        write_json(out.path("report"), report)
    finally:
        if not keep_work:
            shutil.rmtree(work, ignore_errors=True)
        for pattern in (".images.*", ".sparse.*"):
            for leftover in out_dir.glob(pattern):
                shutil.rmtree(leftover, ignore_errors=True)
    log.info("sfm: registered %d/%d images, %d points, %.1f s%s", report["registered"], total,
             report["num_points"], report["timings_s"]["total"],
             f"; PARTIAL, left out: {', '.join(report['unregistered_images'])}" if report["partial"] else "")
    return SfmResult(cams, pts["xyz"], pts["rgb"], report)


def _check_capture(image_dir: Path, cfg: SfmConfig, model_dir: str | Path | None
                   ) -> tuple[list[str], list, dict, str | None]:
    """(readable image names, unreadable ones, headers {name: (w, h, EXIF orientation)}, camera
    mode): the images checked before COLMAP runs (unreadable, fewer than 3, EXIF rotations, sizes)."""
    files = list_images(image_dir)
    good, bad = check_images(files)
    report_unreadable(bad, image_dir, cfg.skip_unreadable)
    require_min_images(len(good), image_dir)
    names = [p.name for p in good]
    headers = image_headers(good)
    rotated = sorted(n for n, (_, _, o) in headers.items() if o != 1)
    if rotated:
        log.warning("%d image(s) carry an EXIF rotation that COLMAP ignores (import them with "
                    "`anigs capture --source photos` to make them upright): %s", len(rotated), ", ".join(rotated[:10]))
    sizes = sorted({(w, h) for w, h, _ in headers.values()})
    try:
        mode = camera_mode(cfg, sizes) if model_dir is None else None
    except ValueError as exc:
        raise ValueError(f"{image_dir}: {exc}") from None
    return names, bad, headers, mode


def _existing_model(model_dir: Path, image_dir: Path, names: list[str], headers: dict, cfg: SfmConfig,
                    report: dict):
    """The given COLMAP model (binary or text; a COLMAP project's ``sparse/0``): checked against the images
    (every image it registers must be there; a folder of the images at another size, such as a project's
    ``images_2``, rescales the cameras; the images it does not register are named in the log) and
    ``min_registered_fraction``."""
    import pycolmap

    total = len(names)
    model_dir = find_model_dir(model_dir)
    try:
        rec = pycolmap.Reconstruction(str(model_dir))
    except Exception as err:  # pycolmap raises plain RuntimeErrors on malformed files
        raise SfmError(f"COLMAP model {model_dir} cannot be read ({err}); check it opens in COLMAP "
                       "(`colmap model_analyzer --path DIR`)") from None
    registered = {rec.images[i].name for i in rec.reg_image_ids()}
    unknown = sorted(registered - set(names))
    if unknown:
        raise ValueError(f"COLMAP model {model_dir} registers images missing from {image_dir}: {unknown[:5]}")
    reg = rec.num_reg_images()
    if reg < cfg.min_registered_fraction * total:
        raise SfmError(f"COLMAP model {model_dir} registers {reg}/{total} images, below "
                       f"min_registered_fraction={cfg.min_registered_fraction}")
    left_out = sorted(set(names) - registered)
    if left_out:
        log.warning("COLMAP model %s does not register %d of the %d images in %s (they are left out): %s",
                    model_dir, len(left_out), total, image_dir, ", ".join(left_out))
    rescaled = _images_size(rec, headers, model_dir, image_dir)
    report["mapping"] = {"source": str(model_dir), "models_found": [reg], "other_models": [], "retries": 0,
                         "model_format": "text" if (model_dir / "cameras.txt").exists()
                         and not (model_dir / "cameras.bin").exists() else "binary"}
    if rescaled:
        report["mapping"]["rescaled_to_images"] = rescaled
    report["status"] = "complete"
    report["refine"] = {"applied": False, "reason": "existing model (no feature database)"}
    return rec


def _images_size(rec, headers: dict, model_dir: Path, image_dir: Path) -> dict | None:
    """Rescale ``rec``'s cameras to the sizes of the images in ``image_dir`` when they are one uniform
    downscale of them (a project's ``images_2``, ``images_4``); None when they already match. Another
    shape is an error naming the image."""
    scales = set()
    for i in rec.reg_image_ids():
        im = rec.images[i]
        cam = rec.cameras[im.camera_id]
        w, h = headers[im.name][:2]
        if (w, h) == (cam.width, cam.height):
            scales.add(1.0)
            continue
        sx, sy = w / cam.width, h / cam.height
        if abs(w - round(cam.width * sy)) > 1 or abs(h - round(cam.height * sx)) > 1:
            raise ValueError(f"{image_dir / im.name} is {w}x{h} but its camera in {model_dir} is {cam.width}x"
                             f"{cam.height} (another shape): point 'images:' at the folder the model was made from")
        scales.add(round(sx, 4))
    if scales == {1.0}:
        return None
    if len(scales) > 1 or any(s > 1 for s in scales):
        raise ValueError(f"the images in {image_dir} are not one uniform downscale of the model's cameras in "
                         f"{model_dir} (scales {sorted(scales)}): point 'images:' at the folder the model was made from")
    log.info("the images in %s are %.4g times the size of the cameras in %s: rescaling the cameras", image_dir,
             next(iter(scales)), model_dir)
    return rescale_model(rec, {n: hw[:2] for n, hw in headers.items()})


def _map(work: Path, image_dir: Path, names: list[str], cfg: SfmConfig, mode: str | None, headers: dict,
         originals: str | Path | None, report: dict):
    """Extraction, matching, mapping with escalation (:mod:`anigs.sfm.escalate`) and refinement;
    fills ``report`` (timings, features, mapping, status, refine); returns the model."""
    stats = steps.extract_and_match(work / "database.db", image_dir, names, cfg, mode)
    report["camera_mode"] = mode
    report["timings_s"].update(extract=stats.pop("extract_s"), match=stats.pop("match_s"))
    report["cpu_s"].update(extract=stats.pop("extract_cpu_s", None), match=stats.pop("match_cpu_s", None))
    report["auto"]["matcher"] = stats.pop("matcher", cfg.matcher)
    report["auto"]["matcher_choice"] = stats.pop("matcher_choice", None)
    report["features"] = stats
    database = work / "database.db"
    report["fingerprints"] = database_fingerprints(database) if database.exists() else {}
    t0, c0 = time.perf_counter(), cpu_seconds()
    first = Source(database, image_dir, "capture", report["auto"]["matcher"])
    outcome = map_escalating(first, work, cfg, names, colmap_device(cfg) if first.database.exists() else None,
                             originals=larger_originals(originals, headers), mode=mode)
    rec, report["mapping"], report["status"] = outcome.rec, outcome.report, outcome.status
    report["timings_s"]["mapping"], report["cpu_s"]["mapping"] = time.perf_counter() - t0, cpu_seconds() - c0
    if (outcome.source.database != database or report["mapping"]["retries"]) and outcome.source.database.exists():
        report["fingerprints"]["kept_database"] = database_fingerprints(outcome.source.database)
    report["fingerprints"]["mapped"] = model_fingerprint(rec)
    t0, c0 = time.perf_counter(), cpu_seconds()
    report["refine"] = refine_model(rec, outcome.source.database, cfg)
    if cfg.mapper_holds_distortion() and not report["refine"]["applied"]:
        report["refine"]["intrinsics_adjustment"] = adjust_intrinsics(rec, cfg.mapper_num_threads)
    if outcome.source.resolution == "original":
        report["mapping"]["rescaled_from_original"] = rescale_model(
            rec, {n: (w, h) for n, (w, h, _) in headers.items()})
    report["timings_s"]["refine"], report["cpu_s"]["refine"] = time.perf_counter() - t0, cpu_seconds() - c0
    report["fingerprints"]["model"] = model_fingerprint(rec)
    return rec


def _undistort(rec, work: Path, out_dir: Path, image_dir: Path, registered: list[str], cfg: SfmConfig,
               report: dict) -> tuple[Any, Path]:
    """(model, temporary images folder): every camera the stage writes is PINHOLE / SIMPLE_PINHOLE
    (undistorted images, or copies when the model has no distortion)."""
    import pycolmap

    t0, c0 = time.perf_counter(), cpu_seconds()
    models = {rec.cameras[rec.images[i].camera_id].model.name for i in rec.reg_image_ids()}
    raw_dir = work / "selected"
    raw_dir.mkdir(exist_ok=True)
    rec.write(raw_dir)
    images_tmp = Path(tempfile.mkdtemp(prefix=".images.", dir=out_dir))
    if not models <= set(UNDISTORTED_MODELS):
        if not cfg.undistort:
            raise ValueError(f"camera model(s) {sorted(models)} have distortion and sfm.undistort is false; "
                             "the project's cameras are pinhole: enable undistort or use PINHOLE/SIMPLE_PINHOLE")
        und = work / "undistorted"
        pycolmap.undistort_images(und, raw_dir, image_dir, image_names=registered, output_type="COLMAP",
                                  num_threads=cfg.num_threads)
        rec = pycolmap.Reconstruction(und / "sparse")
        for n in registered:
            shutil.copy2(und / "images" / n, images_tmp / n)
        report["undistorted"] = True
    else:
        for n in registered:
            shutil.copy2(image_dir / n, images_tmp / n)
        report["undistorted"] = False
    report["camera_models"] = sorted(models)
    report["timings_s"]["undistort"], report["cpu_s"]["undistort"] = time.perf_counter() - t0, cpu_seconds() - c0
    return rec, images_tmp


def _normalise_frame(rec, gt: list[Camera] | None, gt_cameras: str | Path | None, cfg: SfmConfig,
                     report: dict) -> tuple[list[Camera], dict[str, np.ndarray]]:
    """Frame normalisation of ``rec`` in place (module docstring); returns its cameras and points."""
    cams = reconstruction_cameras(rec)
    pts = reconstruction_points(rec)
    if gt is not None:
        by_name = {c.name: c for c in gt}
        missing = [c.name for c in cams if c.name not in by_name]
        if missing:
            raise KeyError(f"ground-truth cameras {gt_cameras} have no entry for image(s) {missing[:5]}")
        sim = umeyama(np.stack([c.center for c in cams]), np.stack([by_name[c.name].center for c in cams]))
        frame = {"mode": "similarity_to_ground_truth", "gt_cameras": str(gt_cameras)}
    else:
        sim, frame = upright_similarity(cams, pts["xyz"], cfg.ground_percentile, cfg.camera_height)
    frame.update(scale=sim.scale, matrix=sim.matrix())
    rec.transform(to_sim3d(sim))
    cams = reconstruction_cameras(rec)
    pts = reconstruction_points(rec)
    report["frame"] = frame
    if gt is not None:
        report["gt_errors"] = pose_errors(cams, gt)
    report["num_points"] = int(len(pts["xyz"]))
    report["mean_reprojection_error_px"] = float(rec.compute_mean_reprojection_error())
    c0 = cams[0]
    report["intrinsics_first_camera"] = {"name": c0.name, "fx": c0.K[0, 0], "fy": c0.K[1, 1], "cx": c0.K[0, 2],
                                         "cy": c0.K[1, 2], "width": c0.width, "height": c0.height}
    return cams, pts
