"""A denser start for sparse captures: points triangulated from two photos at a time.

SfM keeps a point only when it is tracked well across the capture, so a walk past a street keeps a
few thousand: whole facades and shrubs start empty, and the fit fills them by densification from
whatever lies nearest, which the photos it did not train on show as smears. With the photos'
poses known, every pair of neighbouring training photos gives many more points: SIFT matches
guided by the known poses (a match must lie within ``max_epipolar_px`` of its epipolar line),
triangulated (linear, in front of both cameras), and kept where both reprojections land within
``max_reproj_px`` and the rays meet at ``min_angle_deg`` or more (relaxed against COLMAP's 1.5
degrees: a two-view point with a small angle is uncertain in depth, and the fit moves it). This is
ItG-GS's "two-view tracks with relaxed triangulation" (arXiv 2510.17479) without COLMAP's
database: it needs only the posed photos, so a COLMAP project brought in works the same.

Only the training photos are read: the held-out photos judge the fit and must not seed it.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from anigs.cameras import Camera
from anigs.static.warp import nearest_views

log = logging.getLogger("anigs.static.fit")

CONTRAST = 0.01  # SIFT contrast threshold (OpenCV default 0.04): a 640 px photo of a street gives ~1700 features at 0.04


@dataclass(frozen=True)
class PairPoints:
    """Points triangulated from photo pairs: xyz [P,3], rgb [P,3] in [0,1], and what it took."""

    xyz: np.ndarray
    rgb: np.ndarray
    pairs: int
    matches: int

    @property
    def points(self) -> int:
        return int(len(self.xyz))

    def as_dict(self) -> dict:
        return {"points": self.points, "pairs": self.pairs, "matches": self.matches}


def neighbour_pairs(cams: list[Camera], per_photo: int, max_angle_deg: float = 60.0) -> list[tuple[int, int]]:
    """Each photo with its ``per_photo`` nearest photos (:func:`anigs.static.warp.nearest_views`);
    unordered pairs (i < j), sorted."""
    near = nearest_views(cams, per_photo, max_angle_deg)
    return sorted({(min(i, j), max(i, j)) for i, js in enumerate(near) for j in js})


def _features(img: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """SIFT keypoints [K,2] (pixel centres at +0.5, COLMAP's convention, which the cameras use) and
    descriptors [K,128] of a uint8 [H,W,3] photo."""
    grey = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2GRAY)
    sift = cv2.SIFT_create(nfeatures=n, contrastThreshold=CONTRAST)
    kps, desc = sift.detectAndCompute(grey, None)
    if desc is None:
        return np.zeros((0, 2), np.float64), np.zeros((0, 128), np.float32)
    return np.array([k.pt for k in kps], np.float64) + 0.5, desc


def guided_matches(ka: np.ndarray, da: np.ndarray, kb: np.ndarray, db: np.ndarray, F: np.ndarray, ratio: float,
                   max_epipolar_px: float) -> np.ndarray:
    """Index pairs [M,2] of keypoints ``ka`` [A,2], ``kb`` [B,2] (descriptors ``da``, ``db``) matched
    under the known geometry: among the keypoints of b within ``max_epipolar_px`` of a keypoint's
    epipolar line (and the other way round), each other's nearest descriptor, passing Lowe's ratio
    test against the second nearest in that band (COLMAP's guided matching)."""
    if len(ka) < 2 or len(kb) < 2:
        return np.zeros((0, 2), int)
    ha, hb = np.c_[ka, np.ones(len(ka))], np.c_[kb, np.ones(len(kb))]
    la, lb = ha @ F.T, hb @ F  # a's lines in b [A,3], b's lines in a [B,3]
    la /= np.hypot(la[:, 0], la[:, 1]).clip(1e-12)[:, None]
    lb /= np.hypot(lb[:, 0], lb[:, 1]).clip(1e-12)[:, None]
    # the candidates: b's keypoints near a's epipolar lines (one [A,B] float32 product), then the lines
    # the other way round on those few dozen per keypoint only
    near = torch.from_numpy(la.astype(np.float32)) @ torch.from_numpy(hb.T.astype(np.float32))
    ia, ib = (t.numpy() for t in torch.nonzero(near.abs_() <= max_epipolar_px, as_tuple=True))
    back = np.abs((lb[ib] * ha[ia]).sum(1)) <= max_epipolar_px
    ia, ib = ia[back], ib[back]
    if not len(ia):
        return np.zeros((0, 2), int)
    d = np.linalg.norm(da[ia].astype(np.float32) - db[ib].astype(np.float32), axis=1)
    first_a, second_a, best_b = _two_nearest(ia, d, ib, len(ka))
    _, _, best_a = _two_nearest(ib, d, ia, len(kb))
    rows = np.flatnonzero(np.isfinite(first_a) & (first_a < ratio * second_a))
    rows = rows[best_a[best_b[rows]] == rows]  # each other's nearest
    return np.stack([rows, best_b[rows]], 1)


def _two_nearest(key: np.ndarray, d: np.ndarray, other: np.ndarray, n: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per index 0..n-1 of ``key`` [E]: the smallest and second smallest ``d`` [E] among its entries and
    the ``other`` [E] of the smallest (inf, inf, -1 where it has none)."""
    order = np.lexsort((d, key))
    k, dd, oo = key[order], d[order], other[order]
    start = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    first, second, best = np.full(n, np.inf), np.full(n, np.inf), np.full(n, -1)
    first[k[start]], best[k[start]] = dd[start], oo[start]
    has2 = np.r_[start[1:], len(k)] - start > 1
    second[k[start[has2]]] = dd[start[has2] + 1]
    return first, second, best


def _fundamental(a: Camera, b: Camera) -> np.ndarray:
    """F [3,3] with x_b^T F x_a = 0 for pixels of ``a`` and ``b``."""
    R = b.R @ a.R.T
    t = b.t - R @ a.t
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return np.linalg.inv(b.K).T @ tx @ R @ np.linalg.inv(a.K)


def triangulate(a: Camera, b: Camera, xa: np.ndarray, xb: np.ndarray, max_reproj_px: float, min_angle_deg: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Linear triangulation of matched pixels [M,2]; returns (points [P,3], the kept rows [P] of the
    matches): in front of both cameras, both reprojections within ``max_reproj_px``, rays meeting at
    ``min_angle_deg`` or more."""
    Pa, Pb = a.K @ a.viewmat[:3], b.K @ b.viewmat[:3]
    X = cv2.triangulatePoints(Pa, Pb, xa.T.astype(np.float64), xb.T.astype(np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        X = (X[:3] / X[3]).T
    ok = np.isfinite(X).all(1)
    for cam, x in ((a, xa), (b, xb)):
        uv, z = cam.project(np.where(ok[:, None], X, 0.0))
        ok &= (z > 0) & (np.linalg.norm(uv - x, axis=1) <= max_reproj_px)
    ra, rb = X - a.center, X - b.center
    cos = (ra * rb).sum(1) / (np.linalg.norm(ra, axis=1) * np.linalg.norm(rb, axis=1)).clip(1e-12)
    ok &= cos <= np.cos(np.radians(min_angle_deg))
    rows = np.flatnonzero(ok)
    return X[rows], rows


def pair_points(images: list[np.ndarray], cams: list[Camera], per_photo: int = 5, within: np.ndarray | None = None,
                features: int = 8000, ratio: float = 0.8, max_epipolar_px: float = 1.5, max_reproj_px: float = 2.0,
                min_angle_deg: float = 1.0, max_points: int = 0) -> PairPoints:
    """Points from neighbouring pairs of the training photos (uint8 [H,W,3] or float in [0,1], ``cams`` at the
    photos' size). ``within`` [Q,3] (the SfM points): points outside their box (its 1st to 99th
    percentiles, widened on every side by half its largest side) are dropped: a two-view point at a small
    angle can land far off. At most ``max_points`` (0: all): an even subsample, so that the fit's
    Gaussian budget keeps room to densify."""
    images = [_uint8(im) for im in images]
    feats = [_features(im, features) for im in images]
    xyz, rgb, n_matches = [], [], 0
    pairs = neighbour_pairs(cams, per_photo)
    for i, j in pairs:
        (ka, da), (kb, db) = feats[i], feats[j]
        m = guided_matches(ka, da, kb, db, _fundamental(cams[i], cams[j]), ratio, max_epipolar_px)
        if not len(m):
            continue
        xa, xb = ka[m[:, 0]], kb[m[:, 1]]
        n_matches += len(xa)
        X, rows = triangulate(cams[i], cams[j], xa, xb, max_reproj_px, min_angle_deg)
        if not len(rows):
            continue
        xyz.append(X)
        rgb.append(0.5 * (_colour(images[i], xa[rows]) + _colour(images[j], xb[rows])))
    P = np.concatenate(xyz) if xyz else np.zeros((0, 3))
    C = np.concatenate(rgb) if rgb else np.zeros((0, 3))
    if within is not None and len(within) and len(P):
        lo, hi = np.percentile(within, 1, axis=0), np.percentile(within, 99, axis=0)
        pad = 0.5 * float((hi - lo).max())  # isotropic: a flat SfM cloud keeps what lies just off its plane
        ok = ((P >= lo - pad) & (P <= hi + pad)).all(1)
        P, C = P[ok], C[ok]
    if max_points and len(P) > max_points:
        keep = np.linspace(0, len(P) - 1, max_points).round().astype(int)
        P, C = P[keep], C[keep]
    log.info("static fit: %d points triangulated from %d pairs of training photos (%d matches)", len(P), len(pairs),
             n_matches)
    return PairPoints(P, C, len(pairs), n_matches)


def _uint8(img: np.ndarray) -> np.ndarray:
    """A photo as uint8 [H,W,3] (float photos in [0,1] are scaled)."""
    img = np.asarray(img)
    return img if img.dtype == np.uint8 else (np.clip(img, 0, 1) * 255).round().astype(np.uint8)


def _colour(img: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The photo's colour [M,3] in [0,1] at pixels [M,2] (COLMAP's convention: centre at +0.5)."""
    h, w = img.shape[:2]
    c = np.clip(np.floor(x).astype(int), 0, [w - 1, h - 1])
    return img[c[:, 1], c[:, 0]].astype(np.float64) / 255.0
