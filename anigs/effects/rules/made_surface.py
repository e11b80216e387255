"""Rule ``made_surface`` (foliage, grass, flowers; no ground plane needed): a smooth closed surface is a made
thing, not leaves, whatever its colour.

Vegetation is thin and porous: its leaves face every way, and neighbouring splats do not continue one surface. A
pillar, a machine, a bin or a carton is a few smooth surfaces that close around a volume. On the candidate's own
Gaussians (each with its ``neighbours`` nearest Gaussians of the candidate and its splat's normal, the flattest axis):

- ``smooth``: the share of Gaussians whose neighbours continue their splat as one smooth surface does, for at
  least ``min_agree`` of them: the two normals bend by at most ``max_bend_deg`` and each splat lies off the
  other's plane by half that bend, within ``tol_deg`` (two points of one arc; 0 bend on a flat face);
- ``turning``: how far that surface turns, the second eigenvalue of the scatter of those Gaussians' normals (0 for
  one flat sheet, 0.5 for a cylinder, about 1/3 for a box seen from three sides).

The candidate is still when ``smooth`` >= ``min_smooth`` and ``turning`` >= ``MIN_TURNING``: a surface that closes
around a volume. One flat sheet (``turning`` under ``MIN_TURNING``) is left to rule ``plane`` (a wall, a picture).
No ground plane is needed. The figures go on the candidate (``smooth``, ``turning``) and into its reason.

On the real captures' fits (0.13 defaults) no plant candidate passes: their splats face the cameras alike, but
their centres fill a volume, so neighbours do not continue each other's plane (``smooth`` at most 0.50, the fern's
flattened fronds; most under 0.3). The decoys' made things reach 0.56-0.99, their plants 0.00. Nor does the real
courtyard's green bin (0.00-0.15 over three fit seeds): anigs's fits do not lay their splats along surfaces (the
street's facades score 0.10-0.17, and so does a fit whose splats a flatness term made thin), so on real captures
the rule waits for fits whose splats follow their surfaces.

Motivation: on ``courtyard-p30`` (0.12.0) and an indoor hall, a green tractor, green bins, painted pillars and a
carton printed with leaves were chosen as foliage: every rule that kept made things still hung on a ground plane
or on one large flat surface, and colour decided the rest. The decoys ``yard`` and ``hall``
(:mod:`anigs.synth.made_decoys`) rebuild them with a real potted plant that must still move.

Test: ``tests/effects/test_made_surface.py`` (a box, a pillar, leaves, a fit's volume of splats, one sheet),
``tests/effects/test_made_decoys.py`` (the yard and the hall over three seeds).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from anigs.effects.rules.base import Candidate, Context, Verdict, fixed
from anigs.typed_config import Section

MIN_GAUSSIANS = 20  # fewer Gaussians cannot show a surface
MIN_TURNING = 0.1  # a closed surface turns this much at least (second eigenvalue of its normals' scatter)


@dataclass(frozen=True)
class MadeSurface(Section):
    """Rule ``made_surface``: smooth surfaces that close around a volume are made things, whatever their colour."""

    WHERE = "effects.rules.made_surface"

    NAME = "made_surface"
    RENAMED = {"min_turning": fixed("MIN_TURNING", MIN_TURNING, "anigs/effects/rules/made_surface.py")}

    neighbours: int = 8              # a Gaussian's surface: its this many nearest Gaussians of the candidate ...
    max_bend_deg: float = 60.0       # ... continue its splat: their normals bend by at most this ...
    tol_deg: float = 10.0            # ... and each lies off the other's plane by half the bend, within this ...
    min_agree: float = 0.5           # ... for at least this share of them
    min_smooth: float = 0.55         # still: this share of the candidate's Gaussians on smooth surfaces that turn

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        if len(cand.indices) < MIN_GAUSSIANS or ctx.flattest is None:
            return None
        smooth, turning = surface_figures(ctx.means[cand.indices], ctx.flattest[cand.indices], self.neighbours,
                                          self.max_bend_deg, self.tol_deg, self.min_agree)
        cand.figures.update(smooth=smooth, turning=turning)
        if smooth < self.min_smooth or turning < MIN_TURNING:
            return None
        return Verdict(self.NAME, f"a smooth closed surface, not leaves: {smooth:.0%} of its Gaussians continue their "
                                  f"neighbours' surface, which turns around a volume (turning {turning:.2f}), where "
                                  "leaves face every way: a machine, bin, pillar or box does not move, whatever its "
                                  "colour")


def surface_figures(points: np.ndarray, flattest: np.ndarray, k: int, max_bend_deg: float, tol_deg: float,
                    min_agree: float) -> tuple[float, float]:
    """(smooth, turning) of one candidate (module docstring): ``points`` [M,3] its Gaussians' centres, ``flattest``
    [M,3] their unit flattest axes (splat normals). Two neighbouring splats continue one smooth surface when their
    normals bend by at most ``max_bend_deg`` and each lies off the other's plane by half that bend (within
    ``tol_deg``), as two points of one arc do. A Gaussian is on a smooth surface when at least ``min_agree`` of its
    ``k`` nearest others of the candidate continue it; turning: the second eigenvalue of the scatter of those
    Gaussians' normals."""
    m = len(points)
    k = int(min(k, m - 1))
    _, idx = cKDTree(points).query(points, k=k + 1)
    nb = np.asarray(idx).reshape(m, k + 1)[:, 1:]
    off = points[nb] - points[:, None]                                           # [M,k,3]
    dist = np.maximum(np.linalg.norm(off, axis=2), 1e-12)
    off_i = np.arcsin(np.clip(np.abs(np.einsum("nki,ni->nk", off, flattest)) / dist, 0, 1))   # off i's plane
    off_j = np.arcsin(np.clip(np.abs(np.einsum("nki,nki->nk", off, flattest[nb])) / dist, 0, 1))  # off j's plane
    bend = np.arccos(np.clip(np.abs(np.einsum("ni,nki->nk", flattest, flattest[nb])), 0, 1))
    tol = np.radians(tol_deg)
    arc = (bend <= np.radians(max_bend_deg)) & (np.abs(off_i - bend / 2) <= tol) & (np.abs(off_j - bend / 2) <= tol)
    smooth = arc.mean(1) >= min_agree
    turning = 0.0
    if smooth.sum() >= 3:
        n = flattest[smooth]
        turning = float(np.linalg.eigvalsh(n.T @ n / len(n))[1])
    return float(smooth.mean()), turning
