"""A splat trained elsewhere, brought into the sfm folder's frame and checked against the photos.

:func:`import_splat` reads the splat (any format of :func:`anigs.formats.splats.read_splat_file`),
lists the frames it may be in (:func:`frame_candidates`), scores each by rendering a few training
photos small (:func:`score`), keeps the best, and measures it on the training and held-out photos
(``static.holdout_every``) at ``static.imported.eval_max_side``. A splat that does not render the photos
is refused (:class:`SplatFrameError`) before any later stage runs on it.

Frames, each a similarity from the splat's frame to the sfm folder's (``x_sfm = s R x + t``):

- ``cameras``: the trainer's ``cameras.json`` (INRIA 3DGS, OpenSplat): the similarity that takes its
  camera poses onto the sfm folder's same-named cameras (:func:`poses_similarity`: the rotation from the
  camera orientations, so a walk whose cameras lie on a line is solved as well as an orbit; both
  OpenCV and OpenGL camera axes are tried);
- ``sfm``: the sfm folder's own frame (a trainer run on anigs's sfm folder, or a splat anigs wrote);
- ``colmap``: the COLMAP project's frame (INRIA 3DGS on the user's project): the sfm stage's
  normalisation (``sfm/report.json`` ``frame.matrix``);
- ``opensplat``: OpenSplat's centring and scaling recomputed from the COLMAP camera centres (its
  ``cameras.json`` gives the same frame when it is there);
- ``nerfstudio``: ``dataparser_transforms.json`` after nerfstudio's COLMAP axes (or without them);
- ``gsplat``: gsplat's ``normalize_world_space`` recomputed from the COLMAP cameras and points, with
  each sign of its principal axes.

The bar: the kept frame must render the training photos at >= ``min_psnr`` dB and >= ``min_gain_db``
above a flat image of each photo's mean colour. On the demo, OpenSplat's splat in its right frame
scores about 26 dB, the flat image about 11 dB, and the same splat read in the COLMAP frame (missing
OpenSplat's centring and scaling) 9-11 dB (``tests/static/test_imported.py``).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.formats.trainers import (NERFSTUDIO_APPLIED, OPENGL_AXES, TrainerCameras, TrainerFiles,
                                    gsplat_normalisation, opensplat_normalisation, trainer_files)
from anigs.gaussians import Gaussians
from anigs.render import render_gaussians
from anigs.sfm.align import Similarity
from anigs.ssim import fused_ssim, psnr
from anigs.static.config import IMPORT_FRAMES, ImportConfig
from anigs.static.init import split_holdout
from anigs.images import downscale

log = logging.getLogger("anigs.static")

#: photos and size of the quick render that ranks the frames
SCORE_VIEWS, SCORE_SIDE = 4, 160


class SplatFrameError(ValueError):
    """The imported splat does not render the photos in any frame tried."""


@dataclass
class Candidate:
    """One frame the splat may be in: its name, what it rests on, and the similarity to the sfm frame."""

    frame: str
    source: str
    to_sfm: Similarity
    psnr: float = float("nan")  # quick score (dB)


def _sim(M: np.ndarray) -> Similarity:
    """A [4,4] (or [3,4]) similarity matrix ``[s R | t]`` as a :class:`Similarity`."""
    A = np.asarray(M, float)[:3, :4]
    s = float(np.cbrt(np.linalg.det(A[:, :3])))
    if not s > 0:
        raise ValueError(f"not a proper similarity (det {np.linalg.det(A[:, :3]):.3g})")
    return Similarity(s, A[:, :3] / s, A[:, 3].copy())


def _matrix(s: Similarity) -> np.ndarray:
    M = np.eye(4)
    M[:3, :] = s.matrix()
    return M


def poses_similarity(src_rot: np.ndarray, src_centers: np.ndarray, dst_rot: np.ndarray, dst_centers: np.ndarray
                     ) -> tuple[Similarity, float]:
    """The similarity taking camera poses ``src`` onto ``dst`` and its median rotation residual (degrees).

    ``*_rot`` [N,3,3] camera-to-world rotations, ``*_centers`` [N,3]. The rotation is the mean of the
    per-camera rotations ``dst_i src_i^T`` (projected onto SO(3)); scale and shift fit the centres by
    least squares given it (scale 1 when the source centres coincide)."""
    M = np.einsum("nij,nkj->ik", dst_rot, src_rot)
    U, _, Vt = np.linalg.svd(M)
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    a = src_centers @ R.T
    a0, d0 = a - a.mean(0), dst_centers - dst_centers.mean(0)
    spread = float((a0 ** 2).sum())
    s = float((a0 * d0).sum() / spread) if spread > 1e-18 else 1.0
    if not s > 0:
        s = 1.0
    t = dst_centers.mean(0) - s * a.mean(0)
    rel = np.einsum("nij,nkj->nik", dst_rot, R @ src_rot)  # dst_i (R src_i)^T: identity when consistent
    angles = np.degrees(np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    return Similarity(s, R, t), float(np.median(angles))


def _match(tc: TrainerCameras, cameras: Sequence[Camera]) -> list[tuple[int, Camera]]:
    """(index in the trainer's file, camera) pairs by photo name (INRIA drops the extension)."""
    by_name = {c.name: c for c in cameras}
    by_stem = {Path(c.name).stem: c for c in cameras}
    out = []
    for i, n in enumerate(tc.names):
        c = by_name.get(n) or by_stem.get(n) or by_stem.get(Path(n).stem)
        if c is not None:
            out.append((i, c))
    return out


def cameras_candidate(tc: TrainerCameras, cameras: Sequence[Camera]) -> tuple[Candidate, dict]:
    """The ``cameras`` frame of a trainer's ``cameras.json`` and its fit record (matched photos, axes,
    residuals). Raises :class:`SplatFrameError` when fewer than 2 photos share a name."""
    pairs = _match(tc, cameras)
    if len(pairs) < 2:
        raise SplatFrameError(f"{tc.path}: {len(pairs)} of its {len(tc.names)} photos are named as in the sfm "
                              f"folder ({', '.join(tc.names[:3])} ... against {', '.join(c.name for c in cameras[:3])} "
                              "...): it belongs to another capture; set static.imported.frame")
    idx = [i for i, _ in pairs]
    dst_rot = np.stack([c.R.T for _, c in pairs])
    dst_c = np.stack([c.center for _, c in pairs])
    fits = {}
    for axes, flip in (("opencv", np.eye(3)), ("opengl", OPENGL_AXES)):
        fits[axes] = poses_similarity(tc.rotations[idx] @ flip, tc.centers[idx], dst_rot, dst_c)
    axes = min(fits, key=lambda k: fits[k][1])
    sim, rot_res = fits[axes]
    centre_res = np.linalg.norm(sim.apply(tc.centers[idx]) - dst_c, axis=1)
    extent = float(np.linalg.norm(dst_c - dst_c.mean(0), axis=1).max()) or 1.0
    record = {"file": str(tc.path), "matched": len(pairs), "listed": len(tc.names), "axes": axes,
              "rotation_residual_deg": round(rot_res, 4),
              "centre_residual_of_extent": round(float(np.median(centre_res)) / extent, 6)}
    return Candidate("cameras", f"{tc.path.name} ({len(pairs)} photos, {axes} axes)", sim), record


def frame_candidates(files: TrainerFiles, cameras: Sequence[Camera], points: np.ndarray,
                     colmap_to_sfm: Similarity, frame: str = "auto") -> tuple[list[Candidate], list[Candidate], dict]:
    """(the frames the trainer's files give, the conventions to try without them, the cameras.json fit).

    ``cameras``/``points``: the sfm folder's (its frame); ``colmap_to_sfm``: the sfm stage's normalisation
    of the COLMAP project it read. ``frame`` other than auto keeps that frame's candidates only."""
    from_files, record = [], {}
    if files.cameras is not None:
        cand, record = cameras_candidate(files.cameras, cameras)
        from_files.append(cand)
    if files.dataparser is not None:
        to_data = np.linalg.inv(files.dataparser)
        for label, A in (("COLMAP axes", NERFSTUDIO_APPLIED), ("its data frame as COLMAP's", np.eye(3))):
            back = np.eye(4)
            back[:3, :3] = A.T  # data -> COLMAP
            from_files.append(Candidate("nerfstudio", f"{files.dataparser_path.name}, {label}",
                                        colmap_to_sfm.compose(_sim(back @ to_data))))
    conventions = [Candidate("sfm", "the sfm folder's frame", Similarity.identity())]
    if not np.allclose(_matrix(colmap_to_sfm), np.eye(4)):
        conventions.append(Candidate("colmap", "the COLMAP project's frame (INRIA 3DGS)", colmap_to_sfm))
    to_colmap = colmap_to_sfm.inverse()
    c2w = np.stack([_c2w(to_colmap.apply_camera(c)) for c in cameras])
    shift, f = opensplat_normalisation(c2w[:, :3, 3])
    conventions.append(Candidate("opensplat", "OpenSplat's centred and scaled poses",
                                 colmap_to_sfm.compose(Similarity(1 / f, np.eye(3), shift))))
    G = gsplat_normalisation(c2w, to_colmap.apply(points))
    for signs in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)):
        flipped = np.diag([*signs, 1.0]) @ G
        conventions.append(Candidate("gsplat", f"gsplat's normalize_world_space, axes {signs}",
                                     colmap_to_sfm.compose(_sim(np.linalg.inv(flipped)))))
    if frame != "auto":
        keep = lambda cs: [c for c in cs if c.frame == frame]
        return keep(from_files), keep(conventions), record
    return from_files, conventions, record


def _c2w(cam: Camera) -> np.ndarray:
    return np.linalg.inv(cam.viewmat)


def _flat_psnr(img: torch.Tensor) -> float:
    """PSNR of a flat image of ``img``'s mean colour (what a scene that renders nothing useful scores)."""
    return psnr(img.mean((0, 1), keepdim=True).expand_as(img), img)


def _small(images: Sequence[np.ndarray], cameras: Sequence[Camera], side: int) -> tuple[list[torch.Tensor], list[Camera]]:
    ims, cams = [], []
    for im, cam in zip(images, cameras):
        a, c = downscale(im, cam, side)
        ims.append(torch.from_numpy(np.ascontiguousarray(a)).float() / (255.0 if a.dtype == np.uint8 else 1.0))
        cams.append(c)
    return ims, cams


def _render(g: Gaussians, cam: Camera, bg: torch.Tensor) -> torch.Tensor:
    rgb, _, _ = render_gaussians(g, cam, background=bg)
    return rgb.clamp(0, 1)


@torch.no_grad()
def score(g: Gaussians, cand: Candidate, images: Sequence[torch.Tensor], cameras: Sequence[Camera],
          bg: torch.Tensor) -> float:
    """Mean PSNR (dB) of ``g`` read in ``cand``'s frame on the (small) photos: each camera is taken into
    the splat's frame, so the Gaussians are not moved."""
    back = cand.to_sfm.inverse()
    return float(np.mean([psnr(_render(g, back.apply_camera(c), bg), im) for im, c in zip(images, cameras)]))


@torch.no_grad()
def measure(g: Gaussians, images: Sequence[np.ndarray | torch.Tensor], cameras: Sequence[Camera], bg: torch.Tensor,
            side: int = 0) -> dict:
    """Mean PSNR / SSIM of ``g`` and of flat images on the photos, each taken to at most ``side`` px just
    before its render (one photo in float at a time); NaN when there are none."""
    if not images:
        return {"psnr": float("nan"), "ssim": float("nan"), "flat_psnr": float("nan"), "views": 0,
                "size": None}
    ps, ss, flat = [], [], []
    for im, cam in zip(images, cameras):
        if torch.is_tensor(im) and im.is_floating_point() and side == 0:
            small, c = im, cam
        else:
            (small,), (c,) = _small([im.numpy() if torch.is_tensor(im) else im], [cam], side)
        rgb = _render(g, c, bg)
        ps.append(psnr(rgb, small))
        ss.append(float(fused_ssim(rgb, small)))
        flat.append(_flat_psnr(small))
    return {"psnr": float(np.mean(ps)), "ssim": float(np.mean(ss)), "flat_psnr": float(np.mean(flat)),
            "views": len(images), "size": [c.width, c.height]}


def background(cfg: ImportConfig, files: TrainerFiles) -> tuple[tuple[float, float, float], str]:
    """The render background for the check and where it came from."""
    if not isinstance(cfg.background, str):
        return tuple(float(x) for x in cfg.background), "static.imported.background"
    got = files.background()
    if got is not None:
        return got
    return (0.0, 0.0, 0.0), "black (INRIA's, gsplat's default)"


def _describe(cands: Sequence[Candidate]) -> str:
    return "; ".join(f"{c.frame} [{c.source}, scale {c.to_sfm.scale:.3g}]: {c.psnr:.1f} dB" for c in cands)


def import_splat(splat: str | Path, images: Sequence[np.ndarray], cameras: Sequence[Camera], points: np.ndarray,
                 colmap_to_sfm: Similarity, cfg: ImportConfig, holdout_every: int
                 ) -> tuple[Gaussians, dict]:
    """The splat at ``splat`` in the sfm folder's frame, and its record for ``static/metrics.json``.

    Args:
        images: the sfm folder's photos [H,W,3] (uint8 or float in [0,1]), one per camera.
        cameras: their cameras (the sfm folder's ``cameras.json``), sorted as the static fit sorts them.
        points: the sfm folder's points [P,3] (gsplat's normalisation uses them).
        colmap_to_sfm: the sfm stage's normalisation of the COLMAP model it read (``report.json`` frame).
        cfg: ``static.imported``; holdout_every: ``static.holdout_every`` (the held-out photos' split).
    Raises:
        SplatFrameError when no frame renders the training photos over the bar (names the frames
        tried, their scale and PSNR, and the key that sets the frame).
    """
    from anigs.formats.splats import read_splat_file
    from anigs.geometry.transform import transform_gaussians

    t0 = time.perf_counter()
    splat = Path(splat)
    g, fmt = read_splat_file(splat)
    g.check_finite(f"imported splat {splat}")
    if g.num == 0:
        raise ValueError(f"imported splat {splat}: no Gaussians")
    files = trainer_files(splat)
    bg_rgb, bg_from = background(cfg, files)
    bg = torch.tensor(bg_rgb, dtype=torch.float32)
    train_idx, test_idx = split_holdout(len(cameras), holdout_every)
    pick = train_idx[:: max(1, math.ceil(len(train_idx) / SCORE_VIEWS))][:SCORE_VIEWS]
    q_imgs, q_cams = _small([images[i] for i in pick], [cameras[i] for i in pick], SCORE_SIDE)
    q_flat = float(np.mean([_flat_psnr(im) for im in q_imgs]))
    bar = max(cfg.min_psnr, q_flat + cfg.min_gain_db)
    from_files, conventions, cam_record = frame_candidates(files, cameras, points, colmap_to_sfm, cfg.frame)
    tried: list[Candidate] = []
    for group in (from_files, conventions):  # the trainer's own files first; conventions only without a pass
        for c in group:
            c.psnr = score(g, c, q_imgs, q_cams, bg)
            tried.append(c)
        if tried and max(c.psnr for c in tried) >= bar:
            break
    if not tried:
        raise SplatFrameError(f"imported splat {splat}: static.imported.frame is {cfg.frame!r} but nothing beside "
                              f"the splat gives that frame (found: {files.found() or 'no trainer files'})")
    best = max(tried, key=lambda c: c.psnr)
    if not best.psnr >= bar:
        raise SplatFrameError(
            f"imported splat {splat} ({g.num} Gaussians) does not render the photos in any frame tried: best "
            f"{best.psnr:.1f} dB, needs {bar:.1f} dB (static.imported.min_psnr {cfg.min_psnr:g}, or a flat image of "
            f"each photo's mean colour, {q_flat:.1f} dB, + min_gain_db {cfg.min_gain_db:g}). Tried: {_describe(tried)}. "
            f"Trainer files found: {files.found() or 'none'}. Likely cause: the splat was trained on other photos or "
            "cameras, or in a frame whose file is missing (OpenSplat and INRIA write cameras.json beside the splat, "
            "nerfstudio dataparser_transforms.json in its run folder); set static.imported.frame "
            f"({'/'.join(IMPORT_FRAMES[1:])}) or put the trainer's file beside it")
    s = best.to_sfm
    g = transform_gaussians(g, s.scale, s.R, s.t)
    log.info("imported %s (%s, %d Gaussians, SH %d) in the %s frame (%s, scale %.4g): %.2f dB on %d small "
             "photos; other frames: %s", splat, fmt, g.num, g.sh_degree, best.frame, best.source, s.scale, best.psnr,
             len(q_imgs), _describe([c for c in tried if c is not best]) or "none tried")
    side = cfg.eval_max_side
    tr = measure(g, [images[i] for i in train_idx], [cameras[i] for i in train_idx], bg, side)
    te = measure(g, [images[i] for i in test_idx], [cameras[i] for i in test_idx], bg, side)
    record = {
        "train_psnr": tr["psnr"], "train_ssim": tr["ssim"], "train_views": tr["views"],
        "test_psnr": te["psnr"], "test_ssim": te["ssim"], "test_views": te["views"],
        "num_gaussians": g.num, "sh_degree": g.sh_degree, "iterations": 0,
        "image_size": tr["size"] or te["size"],
        "holdout": [cameras[i].name for i in test_idx],
        "seconds": time.perf_counter() - t0,
        "imported": {
            "path": str(splat), "format": fmt, "frame": best.frame, "frame_source": best.source,
            "to_sfm": {"scale": s.scale, "matrix": s.matrix().tolist()},
            "cameras_fit": cam_record or None, "trainer_files": files.found(),
            "background": list(bg_rgb), "background_from": bg_from,
            "flat_psnr": {"train": tr["flat_psnr"], "test": te["flat_psnr"]},
            "bar_db": bar, "frames_tried": [{"frame": c.frame, "source": c.source, "scale": c.to_sfm.scale,
                                             "psnr": c.psnr} for c in tried],
            "score_views": [cameras[i].name for i in pick], "score_side": SCORE_SIDE,
        },
        "accuracy": {"warning": None},
    }
    return g, record


def sfm_frame(report: str | Path | None) -> Similarity:
    """The sfm stage's normalisation of the COLMAP model it read (``report.json`` ``frame.matrix``:
    COLMAP frame -> sfm frame); identity without a report."""
    if report is None:
        return Similarity.identity()
    import json

    frame = json.loads(Path(report).read_text()).get("frame") or {}
    if "matrix" not in frame:
        return Similarity.identity()
    return _sim(np.asarray(frame["matrix"], float))


@torch.no_grad()
def draw_import(g: Gaussians, images: Sequence[np.ndarray], cameras: Sequence[Camera], metrics: dict,
                path: str | Path, rows: int = 3, side: int = 320) -> None:
    """``fit.png`` of an imported splat: per row a photo, the splat's render from its camera and the
    heat map of |render - photo| (the first held-out photos, then training photos), with the PSNRs."""
    import cv2

    from anigs.io import atomic_path

    held = set(metrics.get("holdout", []))
    order = [i for i, c in enumerate(cameras) if c.name in held] + [i for i, c in enumerate(cameras)
                                                                     if c.name not in held]
    bg = torch.tensor(metrics["imported"]["background"], dtype=torch.float32)
    tiles = []
    for i in order[:rows]:
        (im,), (cam,) = _small([images[i]], [cameras[i]], side)
        rgb = _render(g, cam, bg)
        err = (rgb - im).abs().mean(-1).numpy()
        heat = cv2.applyColorMap(np.clip(err / 0.25 * 255, 0, 255).astype(np.uint8), cv2.COLORMAP_INFERNO)[..., ::-1]
        row = np.concatenate([(im.numpy() * 255).astype(np.uint8), (rgb.numpy() * 255).astype(np.uint8), heat], 1)
        row = np.ascontiguousarray(row)
        label = (f"{cam.name} ({'held out' if cam.name in held else 'train'}): {psnr(rgb, im):.2f} dB | photo, "
                 "render, |error| (white: 0.25)")
        cv2.putText(row, label, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(row)
    width = max(t.shape[1] for t in tiles)
    sheet = np.concatenate([np.pad(t, ((0, 4), (0, width - t.shape[1]), (0, 0))) for t in tiles], 0)
    with atomic_path(path) as tmp:
        cv2.imwrite(str(tmp), sheet[..., ::-1])
