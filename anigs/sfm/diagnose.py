"""Why structure from motion registered too few photos, from the attempts' statistics, and what to try.

:func:`likely_causes` reads the matches in the feature database (which photos verified with
which) and the attempts' figures (features per image, verified pairs, models):

- too few features: fewer than ``FEW_FEATURES`` SIFT keypoints per photo (small, blurred or
  textureless photos);
- too little overlap: photos with fewer than ``MIN_NEIGHBOURS`` verified neighbours, or the
  matches split the photos into groups that no verified pair joins (each group a model at best);
- mixed cameras: photos left out although they verified with registered ones (their matches are
  fine, but the one shared camera of ``single_camera: true`` does not fit them: another camera,
  or a zoom).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

FEW_FEATURES = 300  # keypoints per photo below which features are the likely cause
MIN_NEIGHBOURS = 2  # verified neighbours a photo needs to be held in a model
MIN_PAIR_INLIERS = 15  # inlier matches that make a verified pair (COLMAP's min_num_matches)


def match_graph(database: Path) -> tuple[list[str], np.ndarray]:
    """Image names (database order) and [N, N] inlier counts of the verified pairs in ``database``."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        images = sorted(db.read_all_images(), key=lambda im: im.image_id)
        index = {im.image_id: k for k, im in enumerate(images)}
        inliers = np.zeros((len(images), len(images)), np.int64)
        pair_ids, geoms = db.read_two_view_geometries()
        for pid, g in zip(pair_ids, geoms):
            i, j = pycolmap.pair_id_to_image_pair(pid)
            inliers[index[i], index[j]] = inliers[index[j], index[i]] = len(g.inlier_matches)
    finally:
        db.close()
    return [im.name for im in images], inliers


def groups(adjacent: np.ndarray) -> list[list[int]]:
    """Connected components of a boolean [N, N] adjacency, largest first."""
    n = len(adjacent)
    seen, out = np.zeros(n, bool), []
    for s in range(n):
        if seen[s]:
            continue
        stack, comp = [s], []
        seen[s] = True
        while stack:
            k = stack.pop()
            comp.append(k)
            for j in np.flatnonzero(adjacent[k] & ~seen):
                seen[j] = True
                stack.append(int(j))
        out.append(sorted(comp))
    return sorted(out, key=len, reverse=True)


def likely_causes(database: Path | None, attempts: list[dict], registered: list[str],
                  single_camera: bool) -> tuple[list[str], list[str], dict]:
    """Causes (most likely first), settings to try, and the figures behind them."""
    best = max(attempts, key=lambda a: a.get("registered", 0)) if attempts else {}
    kpi = best.get("keypoints_per_image")
    causes, settings = [], []
    facts: dict = {"keypoints_per_image": kpi, "verified_pairs": best.get("verified_pairs"),
                   "models": best.get("models", [])}
    if kpi is not None and kpi < FEW_FEATURES:
        causes.append(f"too few features ({kpi:.0f} SIFT keypoints per photo; small, blurred or textureless photos)")
        settings.append("sfm.sift_peak_threshold: 0.002 (finds fainter features)")
        settings.append("capture.max_side: 0 (import the photos at full size)")
    if database is not None and Path(database).exists():
        names, inliers = match_graph(database)
        adjacent = inliers >= MIN_PAIR_INLIERS
        neighbours = adjacent.sum(1)
        comps = groups(adjacent)
        isolated = [names[k] for k in np.flatnonzero(neighbours < MIN_NEIGHBOURS)]
        reg = set(registered)
        left_out = [k for k, n in enumerate(names) if n not in reg]
        matched_left_out = [names[k] for k in left_out
                            if any(adjacent[k, j] and names[j] in reg for j in range(len(names)))]
        facts.update(match_groups=[len(c) for c in comps], weakly_matched=isolated,
                     left_out_but_matched=matched_left_out,
                     median_verified_neighbours=float(np.median(neighbours)) if len(neighbours) else 0.0)
        if len(comps) > 1 or isolated:
            causes.append(f"too little overlap: the verified pairs split the {len(names)} photos into groups of "
                          f"{[len(c) for c in comps][:6]}; {len(isolated)} photo(s) verified with fewer than "
                          f"{MIN_NEIGHBOURS} others")
            settings.append("sfm.matcher: exhaustive (match every pair)")
            settings.append("take photos between the groups (each view should share most of its content "
                            "with two others)")
        if single_camera and len(matched_left_out) >= max(1, len(left_out) // 2):
            causes.append(f"mixed cameras or zoom: {len(matched_left_out)} photo(s) left out although they "
                          "verified with registered photos (one shared camera does not fit them)")
            settings.append("sfm.single_camera: false (one camera per photo)")
    if len(best.get("models", [])) > 1 and not any(c.startswith("too little overlap") for c in causes):
        causes.append(f"too little overlap: mapping found {len(best['models'])} separate models {best['models']}")
        settings.append("sfm.matcher: exhaustive (match every pair)")
    if not causes:
        causes.append("the photos match but mapping could not grow a model (small baseline or weak geometry)")
    settings.append("sfm.retry_init_min_tri_angle: 2 (accept a narrower initial pair)")
    settings.append("sfm.partial_min_fraction: lower it to continue with fewer photos")
    return causes, list(dict.fromkeys(settings)), facts
