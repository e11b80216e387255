"""The 2AFC answer record: its fields, and the one check shared by the server and the tally.

One answer is one question about one pair, as the study page stores, exports and posts it::

    {
      "schema": "anigs-study-answer/1",
      "study_id": "3f2a9c0d1b7e",     # hash of the built study (pairs, questions, seed)
      "participant": "p-8c1e2f0a9b",  # anonymous id ([A-Za-z0-9_-], at most 64 characters)
      "pair": "demo/view_002/no_composed_v2v",   # scene/view/other variant
      "scene": "demo", "view": "view_002",
      "ours": "full", "other": "no_composed_v2v",   # the two variants compared
      "question": "motion",           # "motion" (realism) or "quality" (visual quality / consistency)
      "left": "no_composed_v2v",      # variant shown on the left
      "side": "right",                # side the participant chose
      "chosen": "full",               # variant the participant chose (follows from left and side)
      "time_ms": 5230.0,              # from the pair being shown (videos playing) to the choice
      "trial": 3, "n_trials": 12,     # position in this participant's order, and the study length
      "answered_at": "2026-11-23T23:40:00.000Z",
      # optional: "seed" (int), "plays" (complete loops watched), "reloaded" (bool),
      #           "received_at" (added by the server)
    }
"""
from __future__ import annotations

import math
import re
from typing import Any

ANSWER_SCHEMA = "anigs-study-answer/1"
EXPORT_SCHEMA = "anigs-study-export/1"
MANIFEST_SCHEMA = "anigs-study-manifest/1"

# question id -> (text on the page, section title of Table 4); Table 4 lists motion first
QUESTIONS: dict[str, tuple[str, str]] = {
    "motion": ("Which video shows more realistic motion?", "Motion realism"),
    "quality": ("Which video has better visual quality, with the scene kept more consistent "
                "(no blur, flicker, or drift of parts that should stay still)?", "Visual quality"),
}

PARTICIPANT_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_STR_FIELDS = ("study_id", "participant", "pair", "scene", "view", "ours", "other", "left", "chosen",
               "answered_at")
REQUIRED = frozenset(_STR_FIELDS) | {"schema", "question", "side", "time_ms", "trial", "n_trials"}
OPTIONAL = frozenset({"seed", "plays", "reloaded", "received_at"})
MAX_STR = 200


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def answer_problems(a: Any) -> list[str]:
    """Everything wrong with one answer record (empty list: valid)."""
    if not isinstance(a, dict):
        return [f"an answer must be a JSON object, got {type(a).__name__}"]
    problems = []
    missing = sorted(REQUIRED - set(a))
    if missing:
        problems.append(f"missing fields {missing}")
    unknown = sorted(set(a) - REQUIRED - OPTIONAL)
    if unknown:
        problems.append(f"unknown fields {unknown}")
    if "schema" in a and a["schema"] != ANSWER_SCHEMA:
        problems.append(f"schema is {a['schema']!r}, expected {ANSWER_SCHEMA!r}")
    for k in _STR_FIELDS:
        if k in a and (not isinstance(a[k], str) or not a[k] or len(a[k]) > MAX_STR):
            problems.append(f"{k!r} must be a non-empty string of at most {MAX_STR} characters")
    if isinstance(a.get("participant"), str) and not PARTICIPANT_RE.match(a["participant"]):
        problems.append("'participant' may only hold letters, digits, '-' and '_' (at most 64)")
    if "question" in a and a["question"] not in QUESTIONS:
        problems.append(f"'question' must be one of {sorted(QUESTIONS)}, got {a['question']!r}")
    if "side" in a and a["side"] not in ("left", "right"):
        problems.append(f"'side' must be 'left' or 'right', got {a['side']!r}")
    t = a.get("time_ms")
    if "time_ms" in a and (not isinstance(t, (int, float)) or isinstance(t, bool) or not math.isfinite(t) or t < 0):
        problems.append(f"'time_ms' must be a finite number >= 0, got {t!r}")
    for k in ("trial", "n_trials"):
        if k in a and (not _is_int(a[k]) or a[k] < (1 if k == "n_trials" else 0)):
            problems.append(f"{k!r} must be an integer >= {1 if k == 'n_trials' else 0}, got {a[k]!r}")
    if _is_int(a.get("trial")) and _is_int(a.get("n_trials")) and a["trial"] >= a["n_trials"] >= 1:
        problems.append(f"'trial' {a['trial']} is not below 'n_trials' {a['n_trials']}")
    for k in ("seed", "plays"):
        if k in a and not _is_int(a[k]):
            problems.append(f"{k!r} must be an integer, got {a[k]!r}")
    if "reloaded" in a and not isinstance(a["reloaded"], bool):
        problems.append("'reloaded' must be true or false")
    if not problems:
        pair = (a["ours"], a["other"])
        if a["ours"] == a["other"]:
            problems.append("'ours' and 'other' must differ")
        if a["left"] not in pair:
            problems.append(f"'left' {a['left']!r} is neither 'ours' nor 'other'")
        elif a["chosen"] != (a["left"] if a["side"] == "left" else pair[1 - pair.index(a["left"])]):
            problems.append(f"'chosen' {a['chosen']!r} contradicts side {a['side']!r} with {a['left']!r} on the left")
    return problems


def answer_key(a: dict[str, Any]) -> tuple[str, str, str, str]:
    """Identity of an answer: one per (study, participant, pair, question)."""
    return a["study_id"], a["participant"], a["pair"], a["question"]


def prefers_ours(a: dict[str, Any]) -> bool:
    return a["chosen"] == a["ours"]
