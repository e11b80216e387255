"""The ground truth of a synthetic capture as the other stages read it: which labels move with which effect."""
from __future__ import annotations

from typing import Sequence


def effects_from_motion(motion: dict) -> dict[str, list[int]]:
    """Effect type -> label ids carrying it, from a ground-truth ``motion.json``.

    Reads ``labels`` ({id: name}) and ``label_effects`` ({name: [effect, ...]}) as written by
    :mod:`anigs.synth`; falls back to ``movable_labels`` as a single effect ``dynamic``.
    """
    if "labels" in motion and "label_effects" in motion:
        out: dict[str, list[int]] = {}
        for lid, name in motion["labels"].items():
            for eff in motion["label_effects"].get(name, []):
                out.setdefault(eff, []).append(int(lid))
        if out:
            return {k: sorted(v) for k, v in out.items()}
    if motion.get("movable_labels"):
        return {"dynamic": [int(i) for i in motion["movable_labels"]]}
    raise KeyError("the motion tables name no moving labels: expected 'labels' + 'label_effects' or 'movable_labels'")


def dynamic_label_ids(effects: dict[str, Sequence[int]]) -> list[int]:
    """All label ids that move under any effect."""
    return sorted({int(i) for ids in effects.values() for i in ids})
