"""The size of a written view queue (json only: the workflow imports it without torch)."""
from __future__ import annotations

import json
from pathlib import Path


def queued_view_count(views_json: str | Path) -> int:
    """Number of queued views in a ``views.json``: its ``views`` list, ids v00..v{n-1}.

    Views the stage dropped (``dynamic_fraction.dropped``) are not counted. Raises ValueError
    when the queue is empty or its ids are not consecutive from v00.
    """
    with open(views_json) as fh:
        views = json.load(fh)["views"]
    ids = [v["id"] for v in views]
    if not ids or ids != [f"v{i:02d}" for i in range(len(ids))]:
        raise ValueError(f"{views_json}: the queued view ids must be v00, v01, ... (at least one), got {ids}")
    return len(ids)
