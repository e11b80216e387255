"""Stage ``effects``: which effects the scene contains, and where (its one region of interest).

Analyses the capture photos the SfM cameras describe (the undistorted ``sfm/images``) with the
fitted static model (:func:`anigs.effects.detect_effects`: colour indices, height above the
fitted ground, planarity, texture, multi-view consistency; no downloaded weights) and decides,
per effect, whether the scene contains it.

The scene's ``effects:`` list picks what may move: ``auto`` (or an empty list) localises only the
kinds the scene's prompt names (:mod:`anigs.effects.vocabulary`: "trees" -> foliage, "garden" ->
foliage, grass and flowers) and takes those detected; a prompt that names nothing that moves gives
a still scene, with the reason; without a prompt every detected effect is taken. An explicit list
overrides the prompt and restricts the effects to those listed. A named or listed effect the scene
does not contain is reported (``requested_not_found``) and skipped, not simulated on an empty
region. The union of the chosen effects' Gaussians is the region of interest
(``dynamic.npy``) that the views stage places the views around.

    anigs effects --canonical static/canonical.ply --cameras sfm/cameras.json --images sfm/images \\
        --out effects/ [--requested foliage_sway flower_bob] [--prompt "a garden"] --params '{...effects section...}'

Writes ``OUT/effects.json`` (per effect: detected, pixel_fraction, gaussian_fraction, confidence,
reason; plus the requested, chosen and skipped effects and ``prompt``: which words matched which kinds), ``OUT/regions.npy`` (int8 [N] region of
each Gaussian, -1 none), ``OUT/dynamic.npy`` (bool [N]) and ``OUT/overview.png``.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.effects.config import REGION_EFFECTS, Config

log = logging.getLogger("anigs.effects")


def is_auto(requested: Sequence[str] | str | None) -> bool:
    """``auto``, None or an empty list: the effects stage (and the prompt) chooses."""
    return requested in (None, "auto") or (not isinstance(requested, str) and len(requested) == 0)


def choose(detected: Sequence[str], requested: Sequence[str] | str | None,
           named: Sequence[str] | None = None) -> tuple[list[str], list[str]]:
    """(effects to simulate, requested effects the scene does not contain).

    ``requested``: ``"auto"``, ``None`` or ``[]`` = every detected effect, or with ``named`` (the
    effects of the kinds the prompt names) those of them that were detected; a list = those of it
    that were detected, in the list's order (the prompt does not matter then)."""
    if is_auto(requested):
        if named is None:
            return list(detected), []
        return [e for e in detected if e in named], [e for e in named if e not in detected]
    if isinstance(requested, str):
        raise ValueError(f"effects: the scene's effects must be 'auto' or a list of effect names, got {requested!r}")
    from anigs.effects.config import EFFECTS

    unknown = [e for e in requested if e not in EFFECTS]
    if unknown:
        raise ValueError(f"effects: unknown effect(s) {unknown} in the scene's effects list; known: {list(EFFECTS)}")
    chosen = [e for e in requested if e in detected]
    return chosen, [e for e in requested if e not in detected]


def run(canonical: str | Path, cameras: str | Path, images: str | Path, out: str | Path, cfg: Config,
        requested: Sequence[str] | str | None = "auto") -> dict:
    """Detect the scene's effects and write the stage's outputs to ``out``; returns ``effects.json``."""
    from anigs.cameras import load_cameras
    from anigs.effects import detect_effects, save_overview
    from anigs.gaussians import load_ply
    from anigs.images import find_image, load_image
    from anigs.io import atomic_path, write_json

    g = load_ply(canonical)
    cams = load_cameras(cameras)
    if not cams:
        raise ValueError(f"{cameras}: no cameras")
    from anigs.effects.detect import photo_indices

    cams = [cams[i] for i in photo_indices(len(cams), cfg.max_photos)]  # only these are analysed: read only them
    photos = [load_image(find_image(Path(images), c.name)) for c in cams]
    from anigs.effects.vocabulary import prompt_kinds

    kinds = prompt_kinds(cfg.prompt) if cfg.prompt is not None else None
    by_prompt = kinds is not None and is_auto(requested)
    res = detect_effects(photos, cams, g, cfg, kinds.regions if by_prompt else None)
    if cfg.drop or cfg.force or cfg.boxes or cfg.selections:
        from anigs.effects.corrections import apply_corrections

        for note in apply_corrections(res, g.means.detach().double().numpy(), cfg.drop, cfg.force, cfg.boxes,
                                      cfg.selections, cfg.selection_tol):
            log.info("effects: correction: %s", note)
    named = None
    if by_prompt:  # the prompt's kinds, and those the user's corrections make move
        named = kinds.effects + [e for r in getattr(res, "user_regions", []) for e in REGION_EFFECTS[r]
                                 if e not in kinds.effects]
    chosen, missing = choose(res.detected, requested, named)
    for e in missing:
        log.warning("effects: %s was asked for but the scene does not contain it: skipped (%s)", e,
                    res.effects[e].reason)
    dynamic = res.dynamic(chosen)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    payload = res.to_json()
    payload.update({"requested": "auto" if is_auto(requested) else list(requested),
                    "chosen": chosen, "requested_not_found": missing,
                    "prompt": {**(kinds.to_json() if kinds is not None else {"prompt": None, "regions": None, "words": {}}),
                               "used": by_prompt, "note": _prompt_note(kinds, by_prompt, chosen)},
                    "corrections": getattr(res, "notes", [])[1:],
                    "num_dynamic": int(dynamic.sum()), "dynamic_fraction": float(dynamic.mean()) if len(dynamic) else 0.0})
    with atomic_path(out / "regions.npy") as tmp, open(tmp, "wb") as fh:
        np.save(fh, res.region_of.astype(np.int8))
    with atomic_path(out / "dynamic.npy") as tmp, open(tmp, "wb") as fh:
        np.save(fh, dynamic)
    save_overview(out / "overview.png", res)
    write_json(out / "effects.json", payload)
    log.info("effects: %s", payload["prompt"]["note"])
    log.info("effects: detected %s; simulating %s (%d of %d Gaussians)%s", res.detected or "nothing",
             chosen or "nothing", int(dynamic.sum()), g.num,
             f"; asked for but not found: {missing}" if missing else "")
    return payload


def _prompt_note(kinds, by_prompt: bool, chosen: Sequence[str]) -> str:
    """One sentence: how the prompt decided what may move."""
    if kinds is None:
        return "no prompt: every detected effect may move"
    if not by_prompt:
        return "the scene's effects list overrides the prompt"
    if not kinds.regions:
        return (f"the prompt {kinds.prompt!r} names nothing that moves (no word of the vocabulary in "
                "anigs/effects/vocabulary.py), so the scene stays still")
    words = "; ".join(f"{w} -> {', '.join(r)}" for w, r in kinds.matches.items())
    return f"the prompt names {', '.join(kinds.regions)} ({words}); only these were looked for" + (
        "" if chosen else ", and none was found, so the scene stays still")


# ---- command line: anigs effects ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p)
    p.add_argument("--cameras", required=True, help="cameras of the photos (sfm/cameras.json)")
    p.add_argument("--images", required=True, help="the undistorted photos the cameras describe (sfm/images)")
    add_out(p, "output folder (effects.json, regions.npy, dynamic.npy, overview.png)")
    p.add_argument("--requested", nargs="*", default=None,
                   help="effects to simulate, instead of the section's `requested` ('auto': the detected kinds the prompt names)")
    p.add_argument("--prompt", default=None, help="the scene's prompt, instead of the section's `prompt`")
    add_params(p, "effects")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    cfg = Config.from_dict(parse_params(args.params))
    if args.prompt is not None:
        cfg.prompt = args.prompt
    requested = cfg.requested if args.requested is None else args.requested  # the section, unless given here
    if requested in ([], ["auto"]):
        requested = "auto"
    run(args.canonical, args.cameras, args.images, args.out, cfg, requested)
    return 0
