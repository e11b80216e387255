"""Rule ``plane`` (foliage, flowers): what lies on large planes is a made surface, not a plant.

Up to ``max_planes`` planes are fitted in turn (RANSAC, the candidate's own draws: checking another
candidate or not does not change its verdict) to the candidate and the non-plant Gaussians within
``near_radius`` x radius of it. A plane counts when it spans ``min_extent`` x radius and is a surface:
the band from one to two ``tol`` x radius off it holds at most ``max_outside`` as many Gaussians as the
plane (a slice through a crown or a bed of flower heads holds more). The candidate is still when the
planes hold at least ``max_share`` of it (within ``tol`` x radius) and it does not rise off them (at most
``max_rising`` as many of its Gaussians within ``rising_band`` tolerances but off the planes as on them):
a facade and its ornaments, a wall, floor or ceiling, a picture, a rug, a mown lawn.

Motivation: the facade, room and lawn decoys (``anigs.synth.decoys``: window surrounds, a green
landscape picture, a red rug, a mown lawn); on the synthetic garden a 35-Gaussian clump of flowers was
once rejected because RANSAC sliced the bed of flower heads into layers (flower recall 0.452 -> 0.408),
hence the surface test and the candidate's own draws. A plant the fit smeared into a sheet is given back
by rule ``smeared_sheet`` (:mod:`anigs.effects.outline`).

Test: ``tests/effects/test_plane_rule.py``, ``tests/effects/test_decoys.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.effects.kinds import REGIONS
from anigs.effects.rules.base import Candidate, Context, Verdict, fixed
from anigs.typed_config import Section

MIN_POINTS = 10  # no plane is fitted to fewer points
OUTSIDE_BAND = 2.0  # a plane's outside band: from one to this many tolerances off it
EXTENT_STDS = 4  # a plane's in-plane extent spans this many standard deviations of its second axis (2 either side)
SAMPLE = 400  # the plane fit's neighbourhood is gathered around at most this many of the candidate's Gaussians


@dataclass(frozen=True)
class Plane(Section):
    """Rule ``plane``: candidates lying on large flat surfaces are still."""

    WHERE = "effects.rules.plane"

    NAME = "plane"
    RENAMED = {"sample": fixed("SAMPLE", SAMPLE, "anigs/effects/rules/plane.py")}

    tol: float = 0.25                # a Gaussian within this x neighbour radius of a plane lies on it
    #: foliage / flowers with this share on a large plane lie on a wall, floor, facade, picture, rug or lawn: still
    max_share: float = 0.6
    min_extent: float = 2.0          # ... on up to max_planes planes each spanning at least this x neighbour radius
    #: ... each a surface: its band from 1 to 2 tol off holds at most this x its Gaussians (a slice through flower
    #: heads holds more)
    max_outside: float = 0.2
    #: ... and the candidate does not rise off them: at most this x as many of its Gaussians within rising_band tol
    #: of the planes but off them as on them (a bush or a bed rises off the ground it stands on)
    max_rising: float = 0.25
    rising_band: float = 3.0         # ... counted within this x tol of the planes
    max_planes: int = 3              # planes fitted in turn (a facade and the lawn at its foot, a wall and a floor)
    near_radius: float = 2.0         # the non-plant Gaussians within this x neighbour radius join the fit ...
    max_points: int = 6000           # ... which uses at most this many points
    ransac_iters: int = 150          # RANSAC draws per plane

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        radius = ctx.radius
        tol = self.tol * radius
        # the part's own RANSAC draws: checking another part (or not) does not change its verdict
        rng = np.random.default_rng((ctx.seed, REGIONS.index(cand.region), int(cand.indices[0])))
        p = ctx.means[cand.indices]
        sub = p[rng.choice(len(p), min(len(p), SAMPLE), replace=False)]
        near = np.unique(np.concatenate(ctx.tree_all.query_ball_point(sub, self.near_radius * radius)).astype(np.int64))
        near = near[~ctx.is_plant[near]]
        ids = np.concatenate([cand.indices, near])
        if len(ids) > self.max_points:
            ids = ids[rng.choice(len(ids), self.max_points, replace=False)]
        on = np.zeros(len(p), bool)
        near_off = np.zeros(len(p), bool)
        extents = []
        rest = ctx.means[ids]
        for _ in range(self.max_planes):
            if len(rest) < MIN_POINTS:
                break
            n, d = fit_plane(rest, tol, rng, self.ransac_iters)
            res = np.abs(rest @ n - d)
            inl = res <= tol
            extent = in_plane_extent(rest[inl], n)
            # a surface: the band just outside the plane's is nearly empty (a slice through a crown is not)
            outside = float(((res > tol) & (res <= OUTSIDE_BAND * tol)).sum() / max(inl.sum(), 1))
            if extent < self.min_extent * radius or outside > self.max_outside:
                break
            extents.append(extent)
            r = np.abs(p @ n - d)
            on |= r <= tol
            near_off |= (r > tol) & (r <= self.rising_band * tol)
            rest = rest[~inl]
        share = float(on.mean())
        rising = float((near_off & ~on).mean()) / max(share, 1e-9)
        cand.figures.update(on_plane=share, rising=rising, planes=len(extents), plane_extent=max(extents, default=0.0))
        if share < self.max_share or rising > self.max_rising:
            return None
        what = 'a large flat surface' if len(extents) == 1 else f'{len(extents)} large flat surfaces'
        return Verdict(self.NAME, f"lies on {what} ({share:.0%} of its Gaussians within {tol:.3g} of planes up to "
                                  f"{max(extents):.3g} across): a wall, facade, floor, ceiling, picture, rug or mown "
                                  "lawn does not move")


def fit_plane(points: np.ndarray, tol: float, rng: np.random.Generator, iters: int) -> tuple[np.ndarray, float]:
    """RANSAC plane (unit normal [3], offset) of ``points`` [M,3] with the most inliers within ``tol``."""
    best, best_n = (np.array([0.0, 0, 1]), 0.0), -1
    m = len(points)
    for _ in range(iters):
        a, b, c = points[rng.choice(m, 3, replace=False)]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n)
        if norm < 1e-12:
            continue
        n /= norm
        cnt = int((np.abs(points @ n - n @ a) <= tol).sum())
        if cnt > best_n:
            best, best_n = (n, float(n @ a)), cnt
    n, d = best
    inl = np.abs(points @ n - d) <= tol
    if inl.sum() >= 3:  # refine on the inliers (least squares)
        p = points[inl]
        mu = p.mean(0)
        n = np.linalg.eigh(np.cov((p - mu).T))[1][:, 0]
        d = float(n @ mu)
    return n, d


def in_plane_extent(points: np.ndarray, normal: np.ndarray) -> float:
    """The smaller in-plane extent (2 x 2 std of the second principal axis) of ``points`` on a plane."""
    if len(points) < 3:
        return 0.0
    p = points - points.mean(0)
    p = p - np.outer(p @ normal, normal)
    ev = np.linalg.eigvalsh(np.cov(p.T))
    return float(EXTENT_STDS * np.sqrt(max(ev[1], 0.0)))
