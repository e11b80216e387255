"""Where a capture's recall goes: the must-move marks through each step of the effects stage, against
what the fit itself allows.

    python benchmarks/real_recall_budget.py --cache DIR [--captures ../shared/captures] [--capture NAME ...]
        [--kind user] [--effects KEY=VALUE ...] [--json OUT] [--sheets DIR]

Per capture, on its cached SfM and fit (``DIR/<capture>/{sfm,static}``, as ``real_captures.py`` leaves
them) and one phrasing of ``benchmarks/real/phrasings.yaml`` (``--kind``, default the user's), the
effects stage runs (:func:`anigs.effects.choice.decide_effects`, with ``--effects`` overrides) and
the labels (``benchmarks/real/labels``) are scored at each step:

- ``2D masks``: per labelled photo the stage analyses, the share of its must-move (and must-stay-still)
  pixels inside the photo's 2D masks of the chosen regions, before the 3D rules (and pooled over them);
- ``lift``: recall / pooled still share / worst still mark of the Gaussians the photos' votes and
  footprints lifted into the chosen regions (rendered as ``real_captures.py`` does);
- ``rules``: the same for the stage's moving Gaussians (after the geometry rules);
- ``bound``: the fit's own limit. Gaussians are chosen by the share of their blending weight, summed
  over the labelled photos, that falls on the must-move marks themselves (an oracle that sees the
  answers; no rule working from the photos does better on these photos), at shares 0.3 to 0.7;
- ``within bar``: the oracle share with the highest recall whose worst still mark moves 1% or less.

A capture whose ``bound`` cannot reach recall 0.8 with every still mark at 1% or less needs a better
fit (more photos); one whose bound can, loses its recall in the steps where the figures drop.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
import real_captures as rc  # noqa: E402
from real.labels import load_labels  # noqa: E402

BOUND_SHARES = (0.3, 0.4, 0.5, 0.55, 0.6, 0.7)
STILL_BAR = 0.01  # the bar: no still mark moves more than this share of its pixels


def mark_shares(g, labels, cams: dict, sizes: dict) -> np.ndarray:
    """Per Gaussian [N]: the share of its blending weight, over the labelled photos, on the must-move marks."""
    from anigs.render.visibility import blend_weights

    total, inside = np.zeros(g.num), np.zeros(g.num)
    for p in labels.photos:
        cam = cams.get(Path(p.name).stem)
        if cam is None:
            continue
        move, _ = p.masks(cam.height, cam.width, sizes[p.name])
        t, w = blend_weights(g, cam, move.astype(np.uint8)[..., None])
        total, inside = total + t, inside + w[:, 0]
    return inside / np.maximum(total, 1e-12)


def stage_steps(g, photos, cams, cfg, requested) -> tuple:
    """The effects stage on the fit, watched: (its :class:`~anigs.effects.choice.Decision`, the lifted
    region per Gaussian [N] before the rules, [(camera name, {region: 2D mask})] of the analysed photos
    before the rules)."""
    from anigs.effects import detect
    from anigs.effects.choice import decide_effects
    from anigs.effects.config import REGIONS

    seen: dict = {}
    lift = detect.lift

    def watched(g_, cues, regions, cfg_):
        seen["masks"] = [(p.camera.name, {k: r.masks[k].copy() for k in REGIONS}) for p, r in zip(cues.maps, regions)]
        out = lift(g_, cues, regions, cfg_)
        seen["lifted"] = out[0].copy()
        return out

    detect.lift = watched  # the step "lift" of detect_effects, watched
    try:
        decision = decide_effects(photos, cams, g, cfg, requested)
    finally:
        detect.lift = lift
    return decision, seen.get("lifted", np.full(g.num, -1)), seen.get("masks", [])


def budget(capture: str, captures: Path, cache: Path, kind: str, overrides: dict, sheets: Path | None = None) -> dict:
    """The figures of one capture (see module docstring)."""
    from anigs.cameras import load_cameras
    from anigs.effects.config import EFFECT_REGION, REGIONS, EffectsConfig
    from anigs.gaussians import load_ply
    from anigs.stages.effects import analysed_photos

    scene = cache / capture
    labels = load_labels(capture)
    ph = next(p for p in rc.phrasings(capture) if p["kind"] == kind)
    g = load_ply(scene / "static" / "canonical.ply")
    all_cams = load_cameras(scene / "sfm" / "cameras.json")
    cfg = EffectsConfig.from_dict({**overrides, "prompt": ph["prompt"], "requested": "auto"})
    photos, picked = analysed_photos(scene / "sfm" / "images", all_cams, cfg)
    decision, lifted, masks = stage_steps(g, photos, picked, cfg, "auto")
    report = decision.report
    regions = sorted({REGIONS.index(EFFECT_REGION[e]) for e in report["chosen"]})
    sizes = rc.photo_sizes(captures, capture, labels)
    cams = {Path(c.name).stem: c for c in all_cams}
    names = [p.name for p in labels.photos]
    out = {"capture": capture, "kind": kind, "prompt": ph["prompt"], "chosen": report["chosen"], "masks": []}
    maps = {"2D masks": {}}
    for p in labels.photos:
        hit = [m for n, m in masks if Path(n).stem == Path(p.name).stem]
        if not hit:
            continue
        region_mask = np.zeros(next(iter(hit[0].values())).shape, bool)
        for k in regions:
            region_mask |= hit[0][REGIONS[k]]
        maps["2D masks"][p.name] = region_mask.astype(np.int8)
        move, still = p.masks(*region_mask.shape, sizes[p.name])
        out["masks"].append({"photo": p.name, "move": float((region_mask & move).sum() / move.sum()) if move.any() else None,
                             "still": float((region_mask & still).sum() / still.sum()) if still.any() else None})
    steps = {"lift": np.isin(lifted, regions), "rules": np.asarray(decision.dynamic, bool)}
    shares = mark_shares(g, labels, cams, sizes)
    steps.update({f"bound {s:g}": shares >= s for s in BOUND_SHARES})
    foliage = np.full(g.num, REGIONS.index("foliage"))  # one tint for every step's moving pixels
    for name, dyn in steps.items():
        maps[name] = rc.moving_of(g, dyn, foliage, cams, names)
    for name, m in maps.items():
        sc = rc.score(labels, m, sizes)
        out[name] = {"gaussians": int(steps[name].sum()) if name in steps else None, "recall": sc["recall"],
                     "still": sc["still"], "worst_still": sc["worst_still"], "worst_what": sc["worst_what"]}
    bar = [out[f"bound {s:g}"] | {"share": s} for s in BOUND_SHARES
           if out[f"bound {s:g}"]["recall"] is not None and out[f"bound {s:g}"]["worst_still"] <= STILL_BAR]
    out["within bar"] = max(bar, key=lambda b: b["recall"], default=None)
    if sheets is not None:
        rc.write_sheet(sheets / f"{capture}.png", capture, captures, labels,
                       [(f"{name} ({kind}: {ph['prompt']})" if name == "2D masks" else name,
                         {"chosen": report["chosen"], "score": out[name], "moving": m}) for name, m in maps.items()])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--captures", type=Path, default=rc.default_captures())
    ap.add_argument("--cache", type=Path, required=True, help="real_captures.py's cache (its fits)")
    ap.add_argument("--capture", nargs="*", default=None, help="captures (default: all labelled)")
    ap.add_argument("--kind", default="user", help="the phrasing kind to run (default: the user's)")
    ap.add_argument("--effects", nargs="*", default=[], help="effects section KEY=VALUE overrides (dotted keys nest: rules.plane.max_share=0.5)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--sheets", type=Path, default=None, help="write DIR/<capture>.png: a column per step, "
                    "moving (or masked) pixels tinted, the marks outlined")
    a = ap.parse_args()
    overrides = rc.nested(rc.parse_kv(a.effects))
    caps = a.capture or sorted(p.stem for p in (rc.REAL / "labels").glob("*.json"))
    rows = []
    print("| capture | step | Gaussians | recall | still moving (worst mark) |\n|---|---|---|---|---|")
    for cap in caps:
        if not (a.cache / cap / "static" / "canonical.ply").exists():
            print(f"<!-- {cap}: no fit in {a.cache / cap}; run real_captures.py first -->")
            continue
        r = budget(cap, a.captures, a.cache, a.kind, overrides, a.sheets)
        rows.append(r)
        for m in r["masks"]:
            print(f"| {cap} | 2D masks, {m['photo']} | | {rc._fmt(m['move'])} (of its marks) | {rc._fmt(m['still'], True)} |")
        for step in ("2D masks", "lift", "rules", *(f"bound {s:g}" for s in BOUND_SHARES)):
            f = r[step]
            print(f"| {cap} | {step} | {f['gaussians'] or ''} | {rc._fmt(f['recall'])} | {rc._fmt(f['still'], True)} "
                  f"({rc._fmt(f['worst_still'], True)} {f['worst_what']}) |", flush=True)
        b = r["within bar"]
        if b is not None:
            print(f"| {cap} | oracle within the still bar (share {b['share']:g}) | {b['gaussians']} | {rc._fmt(b['recall'])} | "
                  f"{rc._fmt(b['still'], True)} ({rc._fmt(b['worst_still'], True)} {b['worst_what']}) |", flush=True)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
