"""Choices the ``sfm`` stage makes from the capture itself: matcher, threads, initial-pair angle.

- :func:`ordering` / :func:`choose_matcher` (after SIFT extraction, which gives the keypoint
  count): ``matcher: auto`` matches exhaustively unless the photos are ordered like a video
  (each photo's successor is among its few most similar ones, on small grey thumbnails: a walk
  or a sweep, frames of a clip) and exhaustive matching would be expensive (images^2/2 x
  keypoints^2 descriptor comparisons above ``exhaustive_max_comparisons``), or there are more
  than ``exhaustive_max_images`` photos; then sequentially (pairs i, i+1, i+2, i+4, ...).
- :func:`similar_pairs`: the sequential matcher also matches each image with its
  ``sequential_similar`` most similar images (same thumbnails), which closes the loop of a capture
  that comes back to where it began (an orbit) and joins the rows of a grid-like sweep.
- :func:`resolve_threads`: ``-1`` = the CPUs this process may use (``os.sched_getaffinity``),
  or the ``anigs --threads N`` that Snakemake passes.
- :func:`initial_pair_angle`: ``init_min_tri_angle: auto`` estimates, from the verified two-view
  geometries already in the database (no RANSAC), each pair's median triangulation angle and starts
  the incremental mapper at the largest of 16, 8, 4, 2, 1 degrees that some pair with enough inliers
  reaches. COLMAP relaxes an initial angle no pair reaches by halving it (with the required inliers)
  and searching all pairs again; on a forward-facing capture that costs several full searches
  (36 of 81 CPU seconds of mapping on the 34-photo flower capture) for the same result.
"""
from __future__ import annotations

import functools
import logging
import math
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

log = logging.getLogger(__name__)

# ``matcher: auto``: fewer photos than this are always matched exhaustively (few pairs either way)
MIN_IMAGES_FOR_SEQUENTIAL = 16
# a photo's successor counts as a neighbour when it is among this many most similar photos
ORDER_RANK = 3
# the photos are ordered when that holds for at least this fraction of them (shuffled: ~3/(n-1))
ORDER_MIN_FRACTION = 0.5
THUMB_WIDTH = 32
# initial angles tried by ``init_min_tri_angle: auto`` (COLMAP's own relaxation halves from 16)
AUTO_INIT_ANGLES = (16.0, 8.0, 4.0, 2.0, 1.0)
AUTO_INIT_MIN_INLIERS = 100  # COLMAP's init_min_num_inliers
AUTO_INIT_MAX_PAIRS = 5000  # pairs examined (most inliers first)


def available_cpus() -> int:
    """CPUs this process may run on (its affinity mask; ``os.cpu_count`` where there is none)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def resolve_threads(num_threads: int, cli_threads: int | None = None) -> int:
    """``num_threads`` as a count: -1 is ``cli_threads`` (``anigs --threads``) when given, else all
    available CPUs."""
    if num_threads > 0:
        return int(num_threads)
    return int(cli_threads) if cli_threads and cli_threads > 0 else available_cpus()


def thumbnails(paths: Sequence[Path], width: int = THUMB_WIDTH) -> np.ndarray:
    """[N, D] grey thumbnails (area-averaged to ``width`` px wide, zero mean, unit variance; all
    at the first image's aspect ratio). Cached for the last few lists of unchanged files."""
    keys = []
    for p in paths:
        st = Path(p).stat()
        keys.append((str(p), st.st_mtime_ns, st.st_size))
    return _thumbnails(tuple(keys), width)


@functools.lru_cache(maxsize=4)
def _thumbnails(keys: tuple, width: int) -> np.ndarray:
    import cv2

    out = []
    shape = None
    for p, _, _ in keys:
        g = cv2.imread(str(p), cv2.IMREAD_REDUCED_GRAYSCALE_2)
        if g is None:
            raise ValueError(f"cannot read image {p}")
        if shape is None:
            shape = (width, max(1, round(width * g.shape[0] / g.shape[1])))
        t = cv2.resize(g.astype(np.float32), shape, interpolation=cv2.INTER_AREA)
        out.append(((t - t.mean()) / (t.std() + 1e-6)).ravel())
    T = np.stack(out)
    T.setflags(write=False)
    return T


def thumbnail_distances(paths: Sequence[Path]) -> np.ndarray:
    """[N, N] Euclidean distances between the thumbnails of ``paths`` (inf on the diagonal)."""
    T = thumbnails(paths).astype(np.float64)
    sq = (T * T).sum(1)
    D = np.sqrt(np.maximum(sq[:, None] + sq[None] - 2 * T @ T.T, 0))
    np.fill_diagonal(D, np.inf)
    return D


def sequential_offsets(n: int, overlap: int) -> set[tuple[int, int]]:
    """Index pairs COLMAP's sequential matcher forms with quadratic overlap: (i, i + 2^k), k < overlap."""
    return {(i, i + (1 << k)) for i in range(n) for k in range(overlap) if i + (1 << k) < n}


def similar_pairs(paths: Sequence[Path], k: int, overlap: int) -> list[tuple[int, int]]:
    """Index pairs (i < j) joining each image to its ``k`` most similar ones (thumbnail distance)
    that the sequential matcher with ``overlap`` does not form; sorted."""
    n = len(paths)
    if k <= 0 or n < 3:
        return []
    D = thumbnail_distances(paths)
    nearest = np.argsort(D, axis=1, kind="stable")[:, :min(k, n - 1)]
    pairs = {(min(i, int(j)), max(i, int(j))) for i in range(n) for j in nearest[i]}
    return sorted(pairs - sequential_offsets(n, overlap))


def ordering(paths: Sequence[Path]) -> dict[str, Any]:
    """How video-like the order of ``paths`` is (sorted by name, as COLMAP numbers them).

    For each photo but the last, the rank of its successor among all other photos by thumbnail
    distance (0: the most similar one). Returns the fraction of successors ranked below
    ``ORDER_RANK``, the median rank and ``ordered`` (fraction >= ``ORDER_MIN_FRACTION``).
    Portrait and landscape photos are compared at one thumbnail size, which only blurs the test.
    """
    n = len(paths)
    if n < 3:
        return {"ordered": False, "successor_near_fraction": 0.0, "successor_median_rank": None}
    D = thumbnail_distances(paths)
    ranks = np.array([int((D[i] < D[i, i + 1]).sum()) for i in range(n - 1)])
    frac = float((ranks < ORDER_RANK).mean())
    return {"ordered": frac >= ORDER_MIN_FRACTION, "successor_near_fraction": round(frac, 3),
            "successor_median_rank": float(np.median(ranks))}


def exhaustive_comparisons(num_images: int, keypoints_per_image: float) -> float:
    """Descriptor comparisons of exhaustive matching: pairs x keypoints^2 (what its time follows:
    about 8 CPU s per 1e9 for the nearest-neighbour search and 10 with the geometric verification, on
    the machine of benchmarks/README.md)."""
    return num_images * (num_images - 1) / 2 * float(keypoints_per_image) ** 2


def choose_matcher(matcher: str, paths: Sequence[Path], exhaustive_max_images: int,
                   exhaustive_max_comparisons: float, keypoints_per_image: float) -> tuple[str, dict[str, Any]]:
    """The matcher to run and why (a report entry); ``matcher`` other than ``auto`` is kept.

    ``auto``: sequential when there are more than ``exhaustive_max_images`` photos, or when the
    photos are ordered (:func:`ordering`) and exhaustive matching would make more than
    ``exhaustive_max_comparisons`` descriptor comparisons (:func:`exhaustive_comparisons`, from the
    keypoints SIFT found); exhaustive otherwise (and always below ``MIN_IMAGES_FOR_SEQUENTIAL``).
    """
    n = len(paths)
    comparisons = exhaustive_comparisons(n, keypoints_per_image)
    info: dict[str, Any] = {"requested": matcher, "images": n, "exhaustive_comparisons": comparisons}
    if matcher != "auto":
        return matcher, {**info, "reason": "set in the config"}
    if n < MIN_IMAGES_FOR_SEQUENTIAL:
        return "exhaustive", {**info, "reason": f"fewer than {MIN_IMAGES_FOR_SEQUENTIAL} images"}
    info.update(ordering(paths))
    if n > exhaustive_max_images:
        if not info["ordered"]:
            log.warning("sfm: %d photos (more than exhaustive_max_images=%d) do not look ordered; matching them "
                        "sequentially may miss pairs (set sfm.matcher: exhaustive to match every pair)",
                        n, exhaustive_max_images)
        return "sequential", {**info, "reason": f"more than exhaustive_max_images={exhaustive_max_images} images"}
    if not info["ordered"]:
        return "exhaustive", {**info, "reason": "unordered photos"}
    if comparisons > exhaustive_max_comparisons:
        return "sequential", {**info, "reason": f"ordered photos and exhaustive matching would make {comparisons:.2g} "
                                                f"comparisons (> exhaustive_max_comparisons={exhaustive_max_comparisons:g})"}
    return "exhaustive", {**info, "reason": f"ordered photos but exhaustive matching is cheap ({comparisons:.2g} "
                                            f"comparisons <= exhaustive_max_comparisons={exhaustive_max_comparisons:g})"}


def pair_triangulation_angles(database: Path, max_pairs: int = AUTO_INIT_MAX_PAIRS) -> tuple[np.ndarray, np.ndarray]:
    """Median triangulation angle (degrees) and inlier count of the verified pairs in ``database``.

    Relative poses come from the stored two-view geometries (E, F or H with their inliers) and
    the database cameras (their prior focal length), as in COLMAP's initial-pair test, without
    RANSAC. At most ``max_pairs`` pairs, most inliers first; pairs whose pose fails are left out.
    """
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        cams = {c.camera_id: c for c in db.read_all_cameras()}
        images = {im.image_id: im for im in db.read_all_images()}
        pair_ids, geoms = db.read_two_view_geometries()
        order = np.argsort([-len(g.inlier_matches) for g in geoms], kind="stable")[:max_pairs]
        keypoints: dict[int, np.ndarray] = {}

        def xy(image_id: int) -> np.ndarray:
            if image_id not in keypoints:
                keypoints[image_id] = np.asarray(db.read_keypoints(image_id), np.float64)[:, :2].copy()
            return keypoints[image_id]

        angles, inliers = [], []
        for k in order:
            g = geoms[k]
            if len(g.inlier_matches) == 0:
                continue
            i1, i2 = pycolmap.pair_id_to_image_pair(pair_ids[k])
            c1, c2 = cams[images[i1].camera_id], cams[images[i2].camera_id]
            try:
                ok = pycolmap.estimate_two_view_geometry_pose(c1, xy(i1), c2, xy(i2), g)
            except Exception:  # noqa: BLE001 - degenerate geometry: leave the pair out
                ok = False
            if ok and math.isfinite(g.tri_angle) and g.tri_angle >= 0:
                angles.append(math.degrees(g.tri_angle))
                inliers.append(len(g.inlier_matches))
    finally:
        db.close()
    return np.asarray(angles), np.asarray(inliers, dtype=np.int64)


def initial_pair_angle(database: Path, fallback: float = 16.0) -> tuple[float, dict[str, Any]]:
    """``init_min_tri_angle: auto``: the first of ``AUTO_INIT_ANGLES`` that a pair with at least
    ``AUTO_INIT_MIN_INLIERS`` inliers (all pairs when none has that many) reaches; ``fallback``
    when no pair pose can be estimated. Returns the angle and a report entry."""
    if not Path(database).exists():
        return fallback, {"angle": fallback, "reason": "no feature database"}
    angles, inliers = pair_triangulation_angles(database)
    if len(angles) == 0:
        return fallback, {"angle": fallback, "reason": "no pair pose could be estimated"}
    strong = angles[inliers >= AUTO_INIT_MIN_INLIERS]
    pool = strong if len(strong) else angles
    best = float(pool.max())
    angle = next((a for a in AUTO_INIT_ANGLES if best >= a), AUTO_INIT_ANGLES[-1])
    info = {"angle": angle, "pairs": int(len(angles)), "pairs_with_enough_inliers": int(len(strong)),
            "largest_pair_angle_deg": round(best, 3), "median_pair_angle_deg": round(float(np.median(pool)), 3)}
    return angle, info
