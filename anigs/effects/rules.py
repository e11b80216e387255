"""Geometry rules out what cannot move: each region's 3D candidates, checked against the model.

The photos' colour rules propose regions; the fitted model says what they lie on. Each region's
Gaussians are split into 3D candidates (connected within ``link`` = ``link_frac`` x the
neighbourhood radius), numbered for the overview and the user's corrections, and checked:

1. *on large planes* (foliage, flowers): a plane fitted (RANSAC) to the candidate and the
   non-plant Gaussians around it holds >= ``plane_max_share`` of the candidate within
   ``plane_tol`` x radius (and does not rise off it: fewer than a quarter as many within three
   times that), spans >= ``plane_min_extent`` x radius and is a surface (at most
   ``plane_max_outside`` as many Gaussians in the band just off it): a facade and its
   ornaments, a wall, floor or ceiling, a picture, a rug, a mown lawn (a low flat lawn is grass
   or nothing). Rejected.
2. *not held by a plant* (flowers): a blossom sits on plant Gaussians; fewer than
   ``min_attached`` of the candidate's Gaussians have a foliage / grass Gaussian or a green one
   within ``link``: a lamp or a window surround seen next to leaves. Rejected.
3. *not a blossom's own colour* (flowers): the candidate's Gaussians carry their own (view-
   independent) colour; at least ``flower_own_min_share`` of a blossom's are saturated and bright
   (saturation >= ``flower_own_min_saturation``, value >= ``flower_own_min_value``, hue outside
   the green band; a bed's stems and leaves make up the rest) or, with ``white_flowers``, at least
   ``flower_own_min_white_share`` are white (not greenish white: glare is white-ish, never a
   saturated colour). Pale, greenish or dull candidates are glare on leaves, bark or a blend of
   them: rejected. So is a white candidate with at least as many pale, bright greenish Gaussians
   (saturation under 0.3, every channel >= 0.6) as white ones and no blossom colour: sunlit glare
   on a frond whitens toward its centre, while white petals are mostly white (rule ``leaf_glare``).
   A white candidate that lies above every camera (along the world's
   up, no ground plane needed) is a light under a ceiling or a bright sky gap: rejected.
4. *sunlit leaves* (flowers): a yellow-green candidate (median hue within ``leaf_hue_margin``
   degrees below the vegetation band) high in a tree's crown (most of it above
   ``crown_min_height`` x the camera height), is foliage in the sun, not blossoms: moved to
   foliage. This rule runs first; the others apply to the candidates it leaves.
5. *blossoms of the named plants* (flowers, only when ``blossoms_of`` is given: the prompt names
   plants but no flowers): a candidate the other rules keep and that the plants of region
   ``blossoms_of`` hold (``min_attached`` of it within ``link`` of their Gaussians) sways with them:
   moved there (a flowering shrub's blossoms). The others stay still and are not numbered (the
   prompt asked for no flowers; a lamp or a bed on a lawn is none of its business).

0. *islands* (opt-in, ``island_min_share`` > 0; foliage, grass, flowers; before the candidates are formed):
   a plant Gaussian with fewer than ``island_min_share`` of its ``island_neighbours`` nearest Gaussians (any
   region) in a plant region is green on something that is not a plant: a mossy stone between leaves, a
   painted gate, a speck on a facade. A plant is a volume of plant Gaussians, so such a Gaussian does not
   move (no colour, no ground plane: only which regions its 3D neighbours were lifted to). It also erodes a
   region's rim where the lift left the rest of the plant unlabelled, so it is off by default: on the
   real-capture benchmark (0.8 default fits) 0.35 lowers the flower capture's still pixels moving from 8.9%
   to 6.4% and the street's gate from 18% to 14%, but also the street's recall from 0.57 to 0.54, and it
   takes 182 of the demo's 3094 moving Gaussians off.

Connected parts of fewer than ``min_candidate`` Gaussians (after the flat / other split, whose
small parts rejoin their component) are checked by the same rules but not numbered (under 3
Gaussians, where no plane can be checked, they do not move); the Gaussians of those set aside
are counted per region (``fragments``).

``check_candidates(...) -> (region_of, candidates, fragments)``: the new region per Gaussian, one
:class:`Candidate` per numbered candidate (kept or rejected, with the reason) and, per region, how
many Gaussians of unnumbered small parts the rules set aside.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from anigs.effects.config import REGIONS, Config

PLANTS = ("foliage", "grass", "flowers")
MAX_PLANES = 3


@dataclass
class Candidate:
    """One numbered 3D candidate region: ``indices`` of its Gaussians and the verdict."""

    number: int
    region: str
    indices: np.ndarray
    centre: np.ndarray
    extent: float
    kept: bool = True
    rule: str = ""
    reason: str = ""
    moved_to: str = ""
    figures: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"number": self.number, "region": self.region, "num_gaussians": int(len(self.indices)),
                "centre": [round(float(x), 4) for x in self.centre], "extent": round(float(self.extent), 4),
                "kept": bool(self.kept), "rule": self.rule, "reason": self.reason, "moved_to": self.moved_to,
                "figures": {k: round(float(v), 4) for k, v in self.figures.items()}}


def point_components(points: np.ndarray, link: float) -> np.ndarray:
    """Connected components [M] (labels 0..) of ``points`` [M,3] linked within ``link``."""
    m = len(points)
    if m == 0:
        return np.zeros(0, np.int64)
    pairs = cKDTree(points).query_pairs(link, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return connected_components(graph, directed=False)[1]


def fit_plane(points: np.ndarray, tol: float, rng: np.random.Generator, iters: int = 150) -> tuple[np.ndarray, float]:
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


def _in_plane_extent(points: np.ndarray, normal: np.ndarray) -> float:
    """The smaller in-plane extent (2 x 2 std of the second principal axis) of ``points`` on a plane."""
    if len(points) < 3:
        return 0.0
    p = points - points.mean(0)
    p = p - np.outer(p @ normal, normal)
    ev = np.linalg.eigvalsh(np.cov(p.T))
    return float(4 * np.sqrt(max(ev[1], 0.0)))


def _hue(rgb: np.ndarray) -> np.ndarray:
    """Hue [M] in degrees of colours [M,3]."""
    import cv2

    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32)[None], cv2.COLOR_RGB2HSV)[0, :, 0]


def check_candidates(means: np.ndarray, colours: np.ndarray, region_of: np.ndarray, height: np.ndarray | None,
                     cam_height: float, radius: float, cfg: Config, flat: np.ndarray | None = None,
                     seed: int = 0, above_cameras: np.ndarray | None = None, blossoms_of: str | None = None
                     ) -> tuple[np.ndarray, list[Candidate], dict[str, int]]:
    """Split each region into numbered 3D candidates and apply the rules (module docstring).

    Args:
        means: Gaussian centres [N,3]; colours: their RGB [N,3] in [0,1].
        region_of: region id [N] (index into ``REGIONS``, -1 none).
        height: height above the ground plane [N] (None: no plane); cam_height: the cameras' height.
        radius: the neighbourhood radius of the local shape (world units).
        flat: bool [N], Gaussians whose neighbourhood is planar: flat and other Gaussians form separate
            candidates (a lawn bank under a tree, a facade behind it are not the crown).
        above_cameras: bool [N], Gaussians higher (along up) than every camera (None: not checked).
        blossoms_of: the region whose plants' blossoms the flowers are (rule 5; None: flowers are their own region).
    Returns the new region ids [N] and the candidates, numbered from 1 in ``REGIONS`` order, largest first.
    """
    out = region_of.copy()
    fragments: dict[str, int] = {}
    if cfg.island_min_share > 0:
        region_of = drop_islands(means, region_of, cfg.island_neighbours, cfg.island_min_share, fragments)
        out = region_of.copy()
    link = cfg.link_frac * radius
    tol = cfg.plane_tol * radius
    plant_ids = [REGIONS.index(r) for r in PLANTS]
    is_plant = np.isin(region_of, plant_ids)
    green = _green(colours, cfg)
    tree_all = cKDTree(means)
    holders = np.flatnonzero(np.isin(region_of, [REGIONS.index("foliage"), REGIONS.index("grass")]) | green)
    holder_tree = cKDTree(means[holders]) if len(holders) else None
    bearers = np.flatnonzero(region_of == REGIONS.index(blossoms_of)) if blossoms_of else np.zeros(0, np.int64)
    bearer_tree = cKDTree(means[bearers]) if len(bearers) else None
    cands: list[Candidate] = []
    for k, name in enumerate(REGIONS):
        idx = np.flatnonzero(region_of == k)
        if not len(idx):
            continue
        lab = point_components(means[idx], link)
        if flat is not None:  # flat parts apart from the rest
            lab = split_flat(lab, flat[idx], cfg.min_candidate)
        sizes = np.bincount(lab)
        for c in np.argsort(-sizes, kind="stable"):
            sel = idx[lab == c]
            # the part's own RANSAC draws: checking another part (or not) does not change its verdict
            rng = np.random.default_rng((seed, k, int(sel[0])))
            p = means[sel]
            cand = Candidate(0, name, sel, p.mean(0), float(np.linalg.norm(p.max(0) - p.min(0))))
            if name == "flowers":
                _sunlit_rule(cand, colours, height, cam_height, cfg)
            if name == "flowers" and not cand.moved_to:
                _own_colour_rule(cand, colours, above_cameras, cfg)
            if name in ("foliage", "flowers") and cand.kept and not cand.moved_to:
                _plane_rule(cand, means, is_plant, tree_all, link, tol, radius, cfg, rng)
            if name == "flowers" and cand.kept and not cand.moved_to:
                _held_rule(cand, means, holder_tree, holders, link, cfg)
            if name == "flowers" and blossoms_of:
                _blossom_rule(cand, means, bearer_tree, blossoms_of, link, cfg)
            if not cand.kept or cand.moved_to:
                out[sel] = REGIONS.index(cand.moved_to) if cand.moved_to else -1
            if name == "flowers" and blossoms_of and not cand.moved_to:
                continue  # flowers the prompt did not ask for: still, not listed
            if sizes[c] >= cfg.min_candidate:
                cands.append(cand)
            else:  # a small part (a lone blossom, a speck on a lawn) is checked, not numbered; under 3
                if sizes[c] < 3:  # Gaussians no plane can be checked: it does not move
                    cand.kept = False
                    out[sel] = -1
                if not cand.kept:
                    fragments[name] = fragments.get(name, 0) + len(sel)
    for i, cand in enumerate(cands):
        cand.number = i + 1
    return out, cands, fragments


def drop_islands(means: np.ndarray, region_of: np.ndarray, k: int, min_share: float,
                 counts: dict[str, int] | None = None) -> np.ndarray:
    """Region ids [N] with the plant Gaussians (``PLANTS``) of ``region_of`` [N] set to -1 where fewer than
    ``min_share`` of their ``k`` nearest other Gaussians (centres ``means`` [N,3]) are plant Gaussians;
    ``counts`` (region -> Gaussians dropped) is updated."""
    plant = np.isin(region_of, [REGIONS.index(r) for r in PLANTS])
    out = region_of.copy()
    if not plant.any():
        return out
    k = int(min(k, len(means) - 1))
    if k < 1:
        return out
    _, nb = cKDTree(means).query(means[plant], k=k + 1)
    share = plant[np.asarray(nb)[:, 1:]].mean(1)
    drop = np.flatnonzero(plant)[share < min_share]
    for r, c in zip(*np.unique(region_of[drop], return_counts=True)):
        if counts is not None:
            counts[REGIONS[int(r)]] = counts.get(REGIONS[int(r)], 0) + int(c)
    out[drop] = -1
    return out


def split_flat(lab: np.ndarray, flat: np.ndarray, min_size: int) -> np.ndarray:
    """Component labels [M] split into their flat and other parts (``flat`` bool [M]); a part smaller
    than ``min_size`` stays with the rest of its component (the rim of a picture whose neighbourhood
    is not planar belongs to the picture), both when both are that small."""
    key = lab * 2 + flat.astype(np.int64)
    size = np.bincount(key, minlength=2 * (lab.max(initial=0) + 1))
    own, sib = size[key], size[key ^ 1]
    small = own < min_size
    key = np.where(small & (sib >= min_size), key ^ 1, key)
    key = np.where(small & (sib < min_size), lab * 2, key)
    return np.unique(key, return_inverse=True)[1]


def _green(colours: np.ndarray, cfg: Config) -> np.ndarray:
    """bool [N]: Gaussians whose own colour is vegetation green (stems, leaves)."""
    hue = _hue(colours)
    mx, mn = colours.max(1), colours.min(1)
    sat = (mx - mn) / np.maximum(mx, 1e-6)
    return (hue >= cfg.green_hue[0]) & (hue <= cfg.green_hue[1]) & (sat >= cfg.green_min_saturation) & \
        (colours[:, 1] >= colours[:, 0])


def _plane_rule(cand: Candidate, means, is_plant, tree_all, link, tol, radius, cfg: Config, rng) -> None:
    """Up to ``MAX_PLANES`` large planes (a facade and the lawn at its foot, a wall and a floor) fitted in
    turn to the candidate and the non-plant Gaussians around it; a plane counts when it spans
    ``plane_min_extent`` x radius and its Gaussians hug it (the band from one to two tolerances off it
    holds at most ``plane_max_outside`` as many Gaussians as the plane: a surface, not a slice through
    a crown or a bed of flower heads); rejected when the planes hold most of the candidate."""
    p = means[cand.indices]
    sub = p[rng.choice(len(p), min(len(p), 400), replace=False)]
    near = np.unique(np.concatenate(tree_all.query_ball_point(sub, 2 * radius)).astype(np.int64))
    near = near[~is_plant[near]]
    ids = np.concatenate([cand.indices, near])
    if len(ids) > 6000:
        ids = ids[rng.choice(len(ids), 6000, replace=False)]
    on = np.zeros(len(p), bool)
    near_off = np.zeros(len(p), bool)
    extents = []
    rest = means[ids]
    for _ in range(MAX_PLANES):
        if len(rest) < 10:
            break
        n, d = fit_plane(rest, tol, rng)
        res = np.abs(rest @ n - d)
        inl = res <= tol
        extent = _in_plane_extent(rest[inl], n)
        # a surface: the band just outside the plane's is nearly empty (a slice through a crown is not)
        outside = float(((res > tol) & (res <= 2 * tol)).sum() / max(inl.sum(), 1))
        if extent < cfg.plane_min_extent * radius or outside > cfg.plane_max_outside:
            break
        extents.append(extent)
        r = np.abs(p @ n - d)
        on |= r <= tol
        near_off |= (r > tol) & (r <= 3 * tol)
        rest = rest[~inl]
    share = float(on.mean())
    rising = float((near_off & ~on).mean()) / max(share, 1e-9)  # a bush or a bed rises off the ground it stands on
    cand.figures.update(on_plane=share, rising=rising, planes=len(extents), plane_extent=max(extents, default=0.0))
    if share >= cfg.plane_max_share and rising <= 0.25:
        cand.kept, cand.rule = False, "plane"
        cand.reason = (f"lies on {'a large flat surface' if len(extents) == 1 else f'{len(extents)} large flat surfaces'} "
                       f"({share:.0%} of its Gaussians within {tol:.3g} of planes up to {max(extents):.3g} across): "
                       "a wall, facade, floor, ceiling, picture, rug or mown lawn does not move")


def _held_rule(cand: Candidate, means, holder_tree, holders, link, cfg: Config) -> None:
    if holder_tree is None:
        share = 0.0
    else:
        d, _ = holder_tree.query(means[cand.indices], k=2, distance_upper_bound=link)
        # a Gaussian holds itself when it is green (a stem): count another holder or a green self
        own = np.isin(cand.indices, holders)
        share = float((np.isfinite(d[:, 1]) | (np.isfinite(d[:, 0]) & ~own)).mean())
    cand.figures["held"] = share
    if share < cfg.min_attached:
        cand.kept, cand.rule = False, "not_held"
        cand.reason = (f"is not held by a plant (only {share:.0%} of its Gaussians lie within {link:.3g} of leaves or "
                       "stems): a blossom grows on a plant, this is a lamp, a window surround or paint seen next to one")


def _blossom_rule(cand: Candidate, means, bearer_tree, bearer: str, link, cfg: Config) -> None:
    """Rule 5: a kept flower candidate that the plants of region ``bearer`` hold sways with them."""
    if not cand.kept or cand.moved_to:
        return
    share = 0.0
    if bearer_tree is not None:
        d, _ = bearer_tree.query(means[cand.indices], k=1, distance_upper_bound=link)
        share = float(np.isfinite(d).mean())
    cand.figures["on_plants"] = share
    if share >= cfg.min_attached:
        cand.moved_to, cand.rule = bearer, "blossoms"
        cand.reason = (f"blossoms on the {bearer} the prompt names ({share:.0%} of its Gaussians within {link:.3g} of a "
                       f"{bearer} Gaussian): they sway with their plant (the prompt names no flowers to bob)")
    else:
        cand.kept, cand.rule = False, "blossoms"
        cand.reason = f"flowers the prompt does not name, on no {bearer} it names: they stay still"


def _sunlit_rule(cand: Candidate, colours, height, cam_height: float, cfg: Config) -> None:
    hue = float(np.median(_hue(colours[cand.indices])))
    cand.figures["hue"] = hue
    lo = cfg.green_hue[0]
    if height is None or not (lo - cfg.leaf_hue_margin <= hue < lo):
        return
    high = float((height[cand.indices] >= cfg.crown_min_height * cam_height).mean())
    cand.figures["in_crown"] = high
    if high >= 0.5:
        cand.moved_to, cand.rule = "foliage", "sunlit_leaves"
        cand.reason = (f"yellow-green (hue {hue:.0f} deg) and high in a crown ({high:.0%} above "
                       f"{cfg.crown_min_height:g} x the camera height): "
                       "sunlit leaves, so they sway with the foliage instead of bobbing as flowers")


def _own_colour_rule(cand: Candidate, colours, above_cameras, cfg: Config) -> None:
    """A blossom's own colour: enough of its Gaussians saturated and bright off the green band, or white
    (module docstring)."""
    rgb = colours[cand.indices]
    mx, mn = rgb.max(1), rgb.min(1)
    sat = (mx - mn) / np.maximum(mx, 1e-6)
    hue = _hue(rgb)
    lo, hi = cfg.flower_green_hue
    coloured = (sat >= cfg.flower_own_min_saturation) & (mx >= cfg.flower_own_min_value) & ~((hue >= lo) & (hue <= hi))
    # white petals; a greenish white (a green hue at saturation >= 0.06) is glare on leaves
    greenish = (hue >= cfg.green_hue[0]) & (hue <= cfg.green_hue[1]) & (sat >= 0.06)
    white = (sat < 0.15) & (mn >= 0.8) & ~greenish if cfg.white_flowers else np.zeros(len(rgb), bool)
    # sunlit glare on leaves: bright, pale and greenish (the bright rim of the white it blends into)
    glare = greenish & (sat < 2 * 0.15) & (mn >= 0.6)
    c_share, w_share, g_share = float(coloured.mean()), float(white.mean()), float(glare.mean())
    cand.figures.update(own_coloured=c_share, own_white=w_share, own_glare=g_share)
    if w_share > c_share and above_cameras is not None:
        high = float(above_cameras[cand.indices].mean())
        cand.figures["above_cameras"] = high
        if high >= 0.5:
            cand.kept, cand.rule = False, "light"
            cand.reason = (f"white and above every camera ({high:.0%} of its Gaussians): a light under a ceiling or "
                           "a bright gap, not blossoms")
            return
    if c_share < cfg.flower_own_min_share and w_share >= cfg.flower_own_min_white_share and g_share >= w_share:
        cand.kept, cand.rule = False, "leaf_glare"
        cand.reason = (f"white ({w_share:.0%}) but as often or more pale green ({g_share:.0%}), with no blossom colour "
                       f"({c_share:.0%}): sunlit glare on leaves, which whitens toward its centre, not white petals")
        return
    if c_share < cfg.flower_own_min_share and w_share < cfg.flower_own_min_white_share:
        cand.kept, cand.rule = False, "not_blossom_colour"
        cand.reason = (f"too few of its Gaussians have a blossom's own colour ({c_share:.0%} saturated and bright off "
                       f"the green band, {w_share:.0%} white; median saturation {float(np.median(sat)):.2f}, value "
                       f"{float(np.median(mx)):.2f}): glare on leaves, bark, soil or a blend of them")
