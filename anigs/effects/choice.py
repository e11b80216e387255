"""Which of the detected effects the scene simulates: the scene's ``effects:`` list and its prompt.

``auto`` (or an empty list) localises only the kinds the scene's prompt names
(:mod:`anigs.effects.vocabulary`) and takes those detected; a prompt that names nothing that moves
gives a still scene, with the reason; without a prompt every detected effect is taken. An explicit
list overrides the prompt and restricts the effects to those listed. A named or listed effect the
scene does not contain is reported (``requested_not_found``) and skipped.

:func:`decide_effects` runs the detection (:func:`anigs.effects.detect_effects`), the user's
corrections and the choice, and gives the effects stage what it writes.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from anigs.effects.config import EFFECTS, REGION_EFFECTS, EffectsConfig
from anigs.effects.corrections import appearance_key, apply_corrections
from anigs.effects.detect import EffectsResult, detect_effects
from anigs.effects.vocabulary import prompt_kinds

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
    unknown = [e for e in requested if e not in EFFECTS]
    if unknown:
        raise ValueError(f"effects: unknown effect(s) {unknown} in the scene's effects list; known: {list(EFFECTS)}")
    chosen = [e for e in requested if e in detected]
    return chosen, [e for e in requested if e not in detected]


def prompt_note(kinds, by_prompt: bool, chosen: Sequence[str]) -> str:
    """One sentence: how the prompt decided what may move."""
    if kinds is None:
        return "no prompt: every detected effect may move"
    if not by_prompt:
        return "the scene's effects list overrides the prompt"
    if not kinds.regions:
        why = ("its words of the vocabulary are negated, said to stay still or depicted"
               if kinds.negated or kinds.depicted else "no word of the vocabulary in anigs/effects/vocabulary.py")
        return f"the prompt {kinds.prompt!r} names nothing that moves ({why}), so the scene stays still"
    words = "; ".join(f"{w} -> {', '.join(r)}" for w, r in kinds.matches.items())
    return f"the prompt names {', '.join(kinds.regions)} ({words}); only these were looked for" + (
        "" if chosen else ", and none was found, so the scene stays still")


def unknown_note(kinds) -> str:
    """One sentence naming the prompt's words the stage did not understand ('' when none)."""
    if kinds is None or not kinds.unknown:
        return ""
    return (f"words of the prompt not understood (in neither the lexicon of anigs/effects/lexicon.py nor the "
            f"English dictionary): {', '.join(kinds.unknown)}; they name nothing that moves")


def switched_off_note(kinds) -> str:
    """One sentence naming the prompt's words that were switched off ('' when none): negated or said to
    stay still ("no flowers", "the flowers stay still") and depicted or made ("a painting of trees",
    "plastic plants")."""
    if kinds is None or not (kinds.negated or kinds.depicted):
        return ""
    parts = []
    if kinds.negated:
        parts.append(f"negated or said to stay still: {', '.join(kinds.negated)}")
    if kinds.depicted:
        parts.append(f"depicted or made, not alive: {', '.join(kinds.depicted)}")
    return f"words of the prompt that name nothing that moves here ({'; '.join(parts)})"


@dataclass
class Decision:
    """``result``: the detection (:class:`~anigs.effects.detect.EffectsResult`, its ``region_of``
    int [N] and ``overview``); ``dynamic``: bool [N] the chosen effects' Gaussians; ``report``: the
    stage's JSON report (the detection plus requested, chosen, requested_not_found, prompt,
    corrections, num_dynamic, dynamic_fraction)."""

    result: EffectsResult
    dynamic: np.ndarray
    report: dict


def decide_effects(photos: Sequence[np.ndarray], cams: Sequence, g, cfg: EffectsConfig,
                   requested: Sequence[str] | str | None) -> Decision:
    """Detect the effects in ``photos`` [H,W,3] seen by ``cams`` with the canonical model ``g``, apply
    the user's corrections (``cfg.drop``, ``force``, ``boxes``, ``selections``) and choose."""
    kinds = prompt_kinds(cfg.prompt) if cfg.prompt is not None else None
    by_prompt = kinds is not None and is_auto(requested)
    res = detect_effects(photos, cams, g, cfg, kinds.regions if by_prompt else None)
    if cfg.drop or cfg.force or cfg.boxes or cfg.selections:
        for note in apply_corrections(res, g.means.detach().double().numpy(), cfg.drop, cfg.force, cfg.boxes,
                                      cfg.selections, cfg.selection_tol, appearance_key(g)):
            log.info("effects: correction: %s", note)
    named = None
    if by_prompt:  # the prompt's kinds, and those the user's corrections make move
        named = kinds.effects + [e for r in res.user_regions for e in REGION_EFFECTS[r]
                                 if e not in kinds.effects]
    chosen, missing = choose(res.detected, requested, named)
    for e in missing:
        log.warning("effects: %s was asked for but the scene does not contain it: skipped (%s)", e,
                    res.effects[e].reason)
    dynamic = res.dynamic(chosen)
    report = res.to_json()
    report.update({"requested": "auto" if is_auto(requested) else list(requested),
                   "chosen": chosen, "requested_not_found": missing,
                   "prompt": {**(kinds.to_json() if kinds is not None else {"prompt": None, "regions": None, "words": {}}),
                              "used": by_prompt, "note": prompt_note(kinds, by_prompt, chosen)},
                   "corrections": res.notes[1:],
                   "num_dynamic": int(dynamic.sum()), "dynamic_fraction": float(dynamic.mean()) if len(dynamic) else 0.0})
    unknown = unknown_note(kinds)
    report["prompt"]["unknown_note"] = unknown
    off = switched_off_note(kinds)
    report["prompt"]["switched_off_note"] = off
    res.prompt_lines = [f"Prompt: {report['prompt']['note']}"] + [x for x in (off, unknown) if x]
    log.info("effects: %s", report["prompt"]["note"])
    if unknown:
        log.warning("effects: %s", unknown)
    log.info("effects: detected %s; simulating %s (%d of %d Gaussians)%s", res.detected or "nothing",
             chosen or "nothing", int(dynamic.sum()), g.num, f"; asked for but not found: {missing}" if missing else "")
    return Decision(res, dynamic, report)
