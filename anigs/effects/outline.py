"""Rule ``smeared_sheet`` (foliage; after the table): is a candidate on a plane a plant the fit smeared into a
sheet? Its outline and its axis in the photos.

A fit made from few photos of a walk cannot place a distant crown in depth: it smears the crown's
Gaussians along the rays of the photos that see it, into a sheet that the 3D plane rule
(:mod:`anigs.effects.rules`) takes for a wall or a floor. Two signs, measured over the analysed
photos that show the candidate, tell such a sheet from a made surface:

1. *along the rays*: the sheet's longest axis points along the rays from those photos' cameras to
   its centre (``along_rays``: median ``|cos|``; a wall, a picture, a rug or a lawn spreads across
   the view, 0.2-0.3 on the synthetic decoys);
2. *free outline*: it stands in front of what lies behind it. Just outside its outline (a ring
   ``RING_FRAC`` x the photo's diagonal wide, around the pixels where it carries at least half of
   the render) the photos see the sky (alpha below ``min_alpha``) or something deeper than
   ``DEPTH_STEP`` x its own depth beside it for a good part of the way round (``free_outline``);
   paint, a picture or a climbing plant flush on a wall shows the wall at its own depth there.

:func:`sheet_signs` returns both per candidate; :func:`release_smeared` keeps the foliage candidates the
plane rule rejected that show both (``effects.rules.smeared_sheet``: ``min_cos``, ``free_outline``).

Motivation: on the street capture (a walk) the 15 dB fit spread a tree at the end of the street along the
rays of the photos that see it: 756 Gaussians on one sheet, which the plane rule set aside as a wall or
floor (recall 0.64 -> 0.49); its sheet runs along the rays (|cos| 0.96) and a quarter of its outline sees
farther things; a picture flush on a wall does neither.

Test: ``tests/effects/test_smeared_sheet.py``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import cv2
import numpy as np

from anigs.effects.geometry import SHOWN, render_features
from anigs.effects.kinds import REGIONS
from anigs.effects.photo_maps import PhotoMaps
from anigs.gaussians import Gaussians
from anigs.typed_config import Section

if TYPE_CHECKING:
    from anigs.effects.rules.base import Candidate

#: a pixel outside the outline is behind the candidate when deeper than this x the candidate's depth beside it
DEPTH_STEP = 1.15
#: the outline ring's width: this x the photo's diagonal (3 px at 400x300), at least 2 px
RING_FRAC = 0.006
#: a photo shows the candidate where it covers at least this many pixels
MIN_PIXELS = 20


@dataclass(frozen=True)
class SmearedSheet(Section):
    """Rule ``smeared_sheet``: foliage the plane rule set aside moves after all when its sheet is a smeared crown."""

    WHERE = "effects.rules.smeared_sheet"

    NAME = "smeared_sheet"

    #: the plane rule's foliage verdict is undone when the sheet is a crown the fit smeared in depth: its longest
    #: axis runs along the rays of the photos that show it (median |cos| at least min_cos; walls, pictures, rugs and
    #: lawns spread across the view) and at least free_outline of its outline ring in those photos sees the sky or
    #: something deeper (paint and pictures lie flush)
    min_cos: float = 0.8
    free_outline: float = 0.15       # ... and this share of its outline sees the sky or deeper (> 1: off)

    def review(self, g: Gaussians, cands: list[Candidate], region_of: np.ndarray, maps: Sequence[PhotoMaps],
               min_alpha: float) -> None:
        """:func:`release_smeared` with these knobs."""
        release_smeared(g, cands, region_of, maps, self, min_alpha)


@dataclass
class SheetSigns:
    """What the photos that show a candidate say of it (nan where no photo shows it)."""

    free_outline: float   # share of its outline ring where the photos see the sky or something deeper
    along_rays: float     # median |cos| between its longest axis and the rays to its centre
    photos: int           # photos that show it


def longest_axis(points: np.ndarray) -> np.ndarray:
    """Unit vector [3]: the direction of largest spread of ``points`` [M,3] (zeros under 3 points)."""
    p = np.asarray(points, np.float64)
    if len(p) < 3:
        return np.zeros(3)
    return np.linalg.eigh(np.cov((p - p.mean(0)).T))[1][:, 2]


def sheet_signs(g: Gaussians, groups: Sequence[np.ndarray], maps: Sequence[PhotoMaps],
                min_alpha: float) -> list[SheetSigns]:
    """Per group of Gaussian indices: its :class:`SheetSigns` over the photos ``maps`` (module docstring)."""
    means = g.means.double().numpy()
    groups = [np.asarray(idx, np.int64) for idx in groups]
    behind, total = np.zeros(len(groups)), np.zeros(len(groups))
    cosines: list[list[float]] = [[] for _ in groups]
    axes = [longest_axis(means[idx]) for idx in groups]
    centres = [means[idx].mean(0) for idx in groups]
    for start in range(0, len(groups), 3):  # three candidates per render pass
        part = list(groups[start:start + 3])
        ind = np.zeros((g.num, len(part)), np.float32)
        for j, idx in enumerate(part):
            ind[idx, j] = 1.0
        for p in maps:
            f, a, d = render_features(g, ind, p.camera)
            h, w = a.shape
            r = max(int(round(RING_FRAC * np.hypot(h, w))), 2)
            kernel = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
            sky = p.alpha < min_alpha
            for j in range(len(part)):
                k = start + j
                own = (f[..., j] >= SHOWN) & (a >= SHOWN)
                if own.sum() < MIN_PIXELS:
                    continue
                ring = (cv2.dilate(own.astype(np.uint8), kernel) > 0) & ~own
                near = cv2.dilate(np.where(own, d, 0).astype(np.float32), kernel)
                behind[k] += int((ring & (sky | (p.depth > DEPTH_STEP * near))).sum())
                total[k] += int(ring.sum())
                ray = centres[k] - np.asarray(p.camera.center, np.float64)
                cosines[k].append(abs(float(axes[k] @ ray)) / max(float(np.linalg.norm(ray)), 1e-12))
    return [SheetSigns(float(behind[k] / total[k]) if total[k] else float("nan"),
                       float(np.median(cosines[k])) if cosines[k] else float("nan"), len(cosines[k]))
            for k in range(len(groups))]


def release_smeared(g: Gaussians, cands: list[Candidate], region_of: np.ndarray, maps: Sequence[PhotoMaps],
                    rule: SmearedSheet, min_alpha: float) -> None:
    """Keep the foliage candidates the plane rule rejected whose sheet runs along the photos' rays (``along_rays``
    >= ``rule.min_cos``) and stands free of what lies behind it (``free_outline`` >= ``rule.free_outline``): a
    crown the fit smeared in depth. ``region_of`` [N] is updated; ``min_alpha``: the photos' sky."""
    on_plane = [c for c in cands if c.rule == "plane" and c.region == "foliage"]
    if not on_plane or rule.free_outline > 1:
        return
    for c, s in zip(on_plane, sheet_signs(g, [c.indices for c in on_plane], maps, min_alpha)):
        c.figures.update(free_outline=float(np.nan_to_num(s.free_outline)), along_rays=float(np.nan_to_num(s.along_rays)))
        if s.along_rays >= rule.min_cos and s.free_outline >= rule.free_outline:
            c.kept, c.rule = True, ""
            c.reason = (f"lies on a large flat sheet in the model, but the sheet runs along the rays of the {s.photos} "
                        f"photos that show it (|cos| {s.along_rays:.2f}) and {s.free_outline:.0%} of its outline there "
                        "sees the sky or something deeper: a plant the fit smeared in depth, not a wall or a floor")
            region_of[c.indices] = REGIONS.index(c.region)
