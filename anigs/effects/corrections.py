"""The user's corrections of what moves (config section ``effects``), applied after detection.

- ``drop: [N, ...]``: the numbered candidates of ``overview.png`` that must not move;
- ``force: [N, ...]``: candidates a geometry rule rejected (or moved) that move in their own region;
- ``boxes: [{min: [x, y, z], max: [x, y, z], effect: NAME | still}]``: the Gaussians whose centres lie
  in the box (world frame of ``static/canonical.ply``) take that effect's region, or never move;
- ``selections: [{ply: PATH, effect: NAME | still}]``: a splat selection exported from SuperSplat (a
  PLY of the selected Gaussians): each selected splat is matched to the fitted Gaussian at its
  position (within ``selection_tol`` x the model's bounding-box diagonal), which takes the effect's
  region or never moves. Fewer than 90% of the selected splats matched is an error (the model was
  moved or rotated in SuperSplat before the export: reset its transform and export again).

``still`` wins over everything else. Candidate numbers are those of the run without corrections
(detection is deterministic, so the overview's numbers stay valid when the scene file changes).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.effects.config import EFFECT_REGION, EFFECTS, REGION_EFFECTS, REGIONS
from anigs.gaussians import load_ply

STILL = "still"
MIN_MATCHED = 0.9


def _check_effect(effect: str, where: str) -> str:
    if effect != STILL and effect not in EFFECTS:
        raise ValueError(f"effects.{where}: effect must be {STILL!r} or one of {list(EFFECTS)}, got {effect!r}")
    return effect


def match_selection(path: str | Path, means: np.ndarray, tol: float) -> np.ndarray:
    """Indices [M] of the Gaussians of ``means`` [N,3] at the selected splats' positions in ``path``."""
    from scipy.spatial import cKDTree


    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"effects.selections: no file {path} (export the selection from SuperSplat as a PLY "
                                "and give its path relative to the folder you run snakemake in)")
    sel = load_ply(path).means.detach().double().numpy()
    diag = float(np.linalg.norm(means.max(0) - means.min(0))) or 1.0
    dist, idx = cKDTree(means).query(sel, k=1)
    ok = dist <= tol * diag
    if len(sel) == 0 or ok.mean() < MIN_MATCHED:
        raise ValueError(f"effects.selections: only {int(ok.sum())} of the {len(sel)} splats in {path} lie at a "
                         f"Gaussian of the fitted model (within {tol * diag:.3g}); was the model moved, rotated or "
                         "scaled in SuperSplat before the export? Reset its transform (or orbit the camera instead) "
                         "and export the selection again")
    return np.unique(idx[ok])


def apply_corrections(res, means: np.ndarray, drop: Sequence[int] = (), force: Sequence[int] = (),
                      boxes: Sequence[dict] = (), selections: Sequence[dict] = (), tol: float = 1e-4) -> list[str]:
    """Apply the corrections to ``res`` (an :class:`~anigs.effects.detect.EffectsResult`) in place: its
    ``region_of`` and each effect's Gaussians and decision; returns one sentence per correction."""
    region = res.region_of.copy()
    never = np.zeros(len(region), bool)
    wanted: set[str] = set()
    by_num = {c.number: c for c in res.candidates}
    notes: list[str] = []

    def cand(n, key):
        if n not in by_num:
            raise ValueError(f"effects.{key}: there is no candidate {n} (the overview sheet numbers 1 to {len(by_num)})")
        return by_num[n]

    for n in force:
        c = cand(n, "force")
        region[c.indices] = REGIONS.index(c.region)
        wanted.add(c.region)
        notes.append(f"#{n} {c.region} ({len(c.indices)} Gaussians) forced to move by the scene file")
    for n in drop:
        c = cand(n, "drop")
        region[c.indices[region[c.indices] == REGIONS.index(c.region)]] = -1
        notes.append(f"#{n} {c.region} ({len(c.indices)} Gaussians) dropped by the scene file: it stays still")

    def assign(inside: np.ndarray, effect: str, what: str) -> None:
        if effect == STILL:
            never[inside] = True
            notes.append(f"{what}: {int(inside.sum())} Gaussians never move")
        else:
            r = EFFECT_REGION[effect]
            region[inside] = REGIONS.index(r)
            wanted.add(r)
            notes.append(f"{what}: {int(inside.sum())} Gaussians join {r} ({effect})")

    for i, b in enumerate(boxes):
        lo, hi = np.asarray(b.get("min"), float), np.asarray(b.get("max"), float)
        if lo.shape != (3,) or hi.shape != (3,) or (lo > hi).any():
            raise ValueError(f"effects.boxes[{i}]: needs min: [x, y, z] and max: [x, y, z] with min <= max, got {b}")
        inside = np.all((means >= lo) & (means <= hi), axis=1)
        assign(inside, _check_effect(b.get("effect", STILL), f"boxes[{i}].effect"), f"box {i} {lo.tolist()}..{hi.tolist()}")
    for i, s in enumerate(selections):
        if "ply" not in s:
            raise ValueError(f"effects.selections[{i}]: needs ply: PATH (a SuperSplat selection export), got {s}")
        idx = match_selection(s["ply"], means, tol)
        inside = np.zeros(len(region), bool)
        inside[idx] = True
        assign(inside, _check_effect(s.get("effect", STILL), f"selections[{i}].effect"), f"selection {s['ply']}")
    region[never] = -1
    _update(res, region, wanted, notes)
    return notes


def _update(res, region: np.ndarray, wanted: set, notes: list[str]) -> None:
    """Each effect's Gaussians and decision from the corrected ``region`` [N]."""
    if not notes:
        return
    res.region_of = region
    n = max(len(region), 1)
    for k, r in enumerate(REGIONS):
        idx = np.flatnonzero(region == k)
        for e in REGION_EFFECTS[r]:
            eff = res.effects[e]
            was = eff.detected
            eff.indices, eff.gaussian_fraction = idx, len(idx) / n
            # a region the corrections leave too small is no longer found, unless the user wants it
            eff.detected = bool(len(idx)) and (r in wanted or (was and len(idx) >= res.cfg.min_gaussians))
            if eff.detected and not was:
                eff.reason = f"{r} moves because the scene file says so ({len(idx)} Gaussians). " + eff.reason
            elif was and not eff.detected:
                eff.reason = (f"No {r}: the scene file's corrections left it {len(idx)} Gaussians "
                              f"(at least {res.cfg.min_gaussians} needed). " + eff.reason)
    res.user_regions = sorted(wanted, key=REGIONS.index)
    res.notes = ["Corrections of the scene file (the tinted masks show the detection before them):"] + notes
