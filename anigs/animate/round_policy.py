"""What a round's model update does, decided from the config (the rules and the update stage ask
here): whether it contains the motion (:func:`contains`), its seed (:func:`round_seed`), a baseline
variant's fit config (:func:`baseline_params`) and why nothing moves (:func:`still_reason`)."""
from __future__ import annotations

import json
from typing import Any

from anigs.animate.config import UpdateConfig


def contains(cfg: UpdateConfig, round_: int | None, rounds: int | None) -> bool:
    """Whether this round's update contains the motion in the masks (``contain``, ``contain_rounds``:
    the final round, or every round; a lone update, without a round plan, does)."""
    return cfg.contain and (cfg.contain_rounds == "every" or round_ is None or rounds is None or round_ == rounds)


def round_seed(seed: int, round_: int) -> int:
    """The seed of round ``round_``'s update (each round draws its own view order and noise)."""
    return seed + 1000 * round_


def baseline_params(animate: dict[str, Any], update: dict[str, Any]) -> dict[str, Any] | None:
    """A baseline variant's fit config (``animate.<method>`` with the update's ``num_bases``); None for ours."""
    m = animate["method"]
    return None if m == "anigs" else {"num_bases": update["num_bases"], **animate[m]}


def baseline_fields(animate: dict[str, Any], update: dict[str, Any]) -> dict[str, str]:
    """A baseline variant's update-stage fields (``--method --method-params``: :func:`baseline_params`
    as canonical JSON); none for ours."""
    p = baseline_params(animate, update)
    return {} if p is None else {"method": animate["method"], "method_params": json.dumps(p, sort_keys=True)}


def still_reason(effects: dict[str, Any]) -> str:
    """Why nothing moves, from the effects stage's report (``effects.json``) when it chose no effect."""
    req = effects.get("requested")
    return (f"the effects stage chose no effect (requested: {req if isinstance(req, str) else ', '.join(req) or 'none'}; "
            f"detected: {', '.join(effects.get('detected') or []) or 'none'}), so nothing moves and no round ran")
