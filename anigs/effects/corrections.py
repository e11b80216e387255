"""The user's corrections of what moves (config section ``effects``), applied after detection.

- ``drop: [N, ...]``: the numbered candidates of ``overview.png`` that must not move;
- ``force: [N, ...]``: candidates a geometry rule rejected (or moved) that move in their own region;
- ``boxes: [{min: [x, y, z], max: [x, y, z], effect: NAME | still, frame: anigs | supersplat}]``: the
  Gaussians whose centres lie in the box take that effect's region, or never move. The corners are in
  the world frame of ``static/canonical.ply`` (``frame: anigs``, the default) or as SuperSplat shows
  positions (``frame: supersplat``: (-x, -y, z) of anigs's frame, :mod:`anigs.formats.orientation`).
  A box that holds no Gaussian is an error; one whose SuperSplat reading holds more Gaussians is
  noted (corners read off SuperSplat without ``frame: supersplat`` select the mirror image);
- ``selections: [{ply: PATH, effect: NAME | still}]``: a splat selection exported from SuperSplat (a
  PLY of the selected Gaussians, plain or "compressed"): each selected splat is matched to the fitted
  Gaussian at its position (within ``selection_tol`` x the model's bounding-box diagonal, plus the
  compressed layout's quantisation step), which takes the effect's region or never moves. A selection
  made on ``export/animated.ply`` or a frame PLY holds moved Gaussians: a plain-PLY splat that matches
  no position is matched by its colour, opacity and scale (which the model update keeps unless
  ``update.param_groups: all``) to the nearest Gaussian that has them, within a tenth of the diagonal. Fewer than 90% of the
  selected splats matched is an error that names the likely cause.

``still`` wins over everything else. Candidate numbers are those of the run without corrections
(detection is deterministic, so the overview's numbers stay valid when the scene file changes).
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from anigs.effects.config import EFFECT_REGION, EFFECTS, REGION_EFFECTS, REGIONS
from anigs.formats.orientation import FRAMES, box_to_anigs

STILL = "still"
MIN_MATCHED = 0.9
#: a selected splat lies within this x the model's diagonal of its Gaussian (the default of effects.selection_tol)
SELECTION_TOL = 1e-4
MATCH_NEAREST = 8  # a selected splat is matched among this many nearest Gaussians (count)
BOX_KEYS = ("min", "max", "effect", "frame")
SELECTION_KEYS = ("ply", "effect")
log = logging.getLogger("anigs.effects")


def _check_keys(entry: dict, allowed: Sequence[str], where: str) -> None:
    unknown = sorted(set(entry) - set(allowed))
    if unknown:
        raise ValueError(f"effects.{where}: unknown key(s) {unknown}; the keys are {list(allowed)}")


def _inside(means: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.all((means >= lo) & (means <= hi), axis=1)


def _check_effect(effect: str, where: str) -> str:
    if effect != STILL and effect not in EFFECTS:
        raise ValueError(f"effects.{where}: effect must be {STILL!r} or one of {list(EFFECTS)}, got {effect!r}")
    return effect


def appearance_key(g) -> np.ndarray:
    """[N,7] what the model update keeps of each Gaussian of ``g``: base colour coefficients, opacity
    logit and log scales (a selection made on a moved model is matched by it)."""
    return torch.cat([g.sh[:, 0], g.opacity_logits[:, None], g.log_scales], 1).detach().double().cpu().numpy()


#: two appearance keys closer than this (max abs difference) are the same Gaussian's
KEY_TOL = 1e-5
#: a selected splat matched by appearance lies within this x the diagonal of its Gaussian
MOVED_MAX = 0.1


def match_selection(path: str | Path, means: np.ndarray, tol: float,
                    appearance: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Indices [M] of the Gaussians of ``means`` [N,3] (with ``appearance`` [N,7], see
    :func:`appearance_key`) at the selected splats of ``path``; and how many splats were matched by
    their appearance rather than their position."""
    from scipy.spatial import cKDTree

    from anigs.formats.splats import load_splats

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"effects.selections: no file {path} (export the selection from SuperSplat as a PLY "
                                "and give its path relative to the folder you run snakemake in)")
    sel, step, layout = load_splats(path)
    pts = sel.means.detach().double().numpy()
    diag = float(np.linalg.norm(means.max(0) - means.min(0))) or 1.0
    radius = tol * diag + np.linalg.norm(step, axis=1)  # compressed: a full quantisation step (the writer rounds)
    k = min(MATCH_NEAREST, len(means))
    dist, idx = cKDTree(means).query(pts, k=k)
    dist, idx = dist.reshape(len(pts), k), idx.reshape(len(pts), k)
    near = dist <= radius[:, None]
    rows = np.arange(len(pts))
    pick = np.zeros(len(pts), int)  # the nearest within the tolerance ...
    key = appearance_key(sel) if appearance is not None else None
    if key is not None:
        diff = np.abs(appearance[idx] - key[:, None]).max(-1)  # [M,k]
        if layout == "compressed ply":  # ... or, within a coarse step, the most alike
            pick = np.where(near, diff, np.inf).argmin(1)
        else:  # ... or the one that is the same Gaussian (a moved neighbour may sit within the tolerance)
            same = near & (diff <= KEY_TOL)
            pick = np.where(same.any(1), same.argmax(1), 0)
    ok, found = near[rows, pick], idx[rows, pick]
    moved = 0
    miss = np.zeros(0, int)
    if key is not None and layout == "ply":
        # plain PLY: a splat whose position holds no Gaussian that looks like it had moved (animated.ply, a frame)
        miss = np.flatnonzero(~(near & (diff <= KEY_TOL)).any(1))
    if len(miss):
        kd, kidx = cKDTree(appearance).query(key[miss], k=k, p=np.inf)
        kd, kidx = kd.reshape(len(miss), k), kidx.reshape(len(miss), k)
        # of the Gaussians that look the same (clones, flat synthetic colours), the nearest
        far = np.where(kd <= KEY_TOL, np.linalg.norm(means[kidx] - pts[miss, None], axis=-1), np.inf)
        best = far.argmin(1)
        rows_m = np.arange(len(miss))
        hit = far[rows_m, best] <= MOVED_MAX * diag
        ok[miss[hit]] = True
        found[miss[hit]] = kidx[rows_m, best][hit]
        moved = int(hit.sum())
        # no Gaussian looks like it anywhere near (a tool changed its colours): its position decides, as above
    if len(pts) == 0 or ok.mean() < MIN_MATCHED:
        how = "" if appearance is None or layout != "ply" else " or carry the colour, opacity and scale of a Gaussian nearby"
        raise ValueError(
            f"effects.selections: only {int(ok.sum())} of the {len(pts)} splats in {path} ({layout}) lie at a Gaussian "
            f"of the fitted model (within {tol * diag:.3g}{' plus its quantisation step' if layout != 'ply' else ''})"
            f"{how}. Either the model was moved, rotated or scaled in SuperSplat before the export (reset its "
            "transform, orbit the camera instead, and export the selection again), or the selection was made on a "
            "file whose Gaussians are not those of static/canonical.ply (a compressed PLY of animated.ply or of a "
            "frame, a model updated with update.param_groups: all, another run's model): select on "
            "static/canonical.ply and export again")
    return np.unique(found[ok]), moved


def apply_corrections(res, means: np.ndarray, drop: Sequence[int] = (), force: Sequence[int] = (),
                      boxes: Sequence[dict] = (), selections: Sequence[dict] = (), tol: float = SELECTION_TOL,
                      appearance: np.ndarray | None = None) -> list[str]:
    """Apply the corrections to ``res`` (an :class:`~anigs.effects.detect.EffectsResult`) in place: its
    ``region_of`` and each effect's Gaussians and decision; returns one sentence per correction.
    ``means`` [N,3] and ``appearance`` [N,7] (:func:`appearance_key`) are the fitted Gaussians'."""
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
        _check_keys(b, BOX_KEYS, f"boxes[{i}]")
        lo, hi = np.asarray(b.get("min"), float), np.asarray(b.get("max"), float)
        if lo.shape != (3,) or hi.shape != (3,) or (lo > hi).any():
            raise ValueError(f"effects.boxes[{i}]: needs min: [x, y, z] and max: [x, y, z] with min <= max, got {b}")
        frame = b.get("frame", "anigs")
        if frame not in FRAMES:
            raise ValueError(f"effects.boxes[{i}].frame: one of {list(FRAMES)} (the frame its corners are read in), "
                             f"got {frame!r}")
        inside = _inside(means, *box_to_anigs(lo, hi, frame))
        what = f"box {i} {lo.tolist()}..{hi.tolist()}" + (f" ({frame} frame)" if frame != "anigs" else "")
        other = "supersplat" if frame == "anigs" else "anigs"
        mirrored = int(_inside(means, *box_to_anigs(lo, hi, other)).sum())
        if not inside.any():
            hint = (f"; read in the {other} frame it would hold {mirrored}: set frame: {other}" if mirrored else "")
            raise ValueError(f"effects.boxes[{i}]: the box {lo.tolist()}..{hi.tolist()} ({frame} frame) holds no Gaussian "
                             f"of the model, which spans {means.min(0).round(3).tolist()}..{means.max(0).round(3).tolist()} "
                             f"in anigs's frame{hint}")
        if "frame" not in b and mirrored > inside.sum():
            what += (f" [the same corners in SuperSplat's frame (-x, -y, z) hold {mirrored}: if you read them off "
                     "SuperSplat, add frame: supersplat]")
            log.warning("effects.boxes[%d]: %s", i, what)
        assign(inside, _check_effect(b.get("effect", STILL), f"boxes[{i}].effect"), what)
    for i, s in enumerate(selections):
        if "ply" not in s:
            raise ValueError(f"effects.selections[{i}]: needs ply: PATH (a SuperSplat selection export), got {s}")
        _check_keys(s, SELECTION_KEYS, f"selections[{i}]")
        idx, moved = match_selection(s["ply"], means, tol, appearance)
        inside = np.zeros(len(region), bool)
        inside[idx] = True
        what = f"selection {s['ply']}" + (f" ({moved} splats had moved: matched by colour, opacity and scale)" if moved else "")
        assign(inside, _check_effect(s.get("effect", STILL), f"selections[{i}].effect"), what)
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
            eff.detected = bool(len(idx)) and (r in wanted or (was and len(idx) >= res.cfg.decide.min_gaussians))
            if eff.detected and not was:
                eff.reason = f"{r} moves because the scene file says so ({len(idx)} Gaussians). " + eff.reason
            elif was and not eff.detected:
                eff.reason = (f"No {r}: the scene file's corrections left it {len(idx)} Gaussians "
                              f"(at least {res.cfg.decide.min_gaussians} needed). " + eff.reason)
    res.user_regions = sorted(wanted, key=REGIONS.index)
    res.notes = ["Corrections of the scene file (the tinted masks show the detection before them):"] + notes
