"""Shared check of the stages' config dataclasses: unknown keys are an error naming them."""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping


def reject_unknown_keys(cls: type, d: Mapping[str, Any], where: str, error: type[Exception] = ValueError) -> None:
    """Raise ``error`` naming every key of ``d`` that is not a field of dataclass ``cls``."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - known)
    if unknown:
        raise error(f"{where}: unknown keys {unknown}; allowed: {sorted(known)}")
