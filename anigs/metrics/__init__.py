"""Evaluation metrics: Fréchet distance, FVD/FID features (the torch I3D, TorchScript; local weights), image
metrics, weight-free motion metrics and the multiview-consistency protocol.

Every metric is written into ``metrics.json`` as a *record* (see :mod:`anigs.reports.tables` for
the file schema): :func:`metric_record` for a computed value, :func:`not_available` for a
metric that could not be computed (missing weights, no reference clips, no masks...).
"""
from __future__ import annotations

import math
from typing import Any

from anigs.metrics.frechet import FrechetResult, feature_stats, frechet_distance, frechet_distance_from_stats

__all__ = ["FrechetResult", "feature_stats", "frechet_distance", "frechet_distance_from_stats",
           "metric_record", "not_available"]


def metric_record(value: float, higher_is_better: bool, unit: str = "", protocol: dict[str, Any] | None = None,
                  samples: dict[str, int] | None = None, warnings: list[str] | None = None,
                  **extra: Any) -> dict[str, Any]:
    """A computed metric: value (NaN -> not available, with the reason 'no valid samples')."""
    value = float(value)
    if math.isnan(value):
        return not_available("no valid samples (empty region or too few frames)", higher_is_better, unit,
                             protocol, samples)
    rec = {"value": value, "available": True, "reason": None, "higher_is_better": bool(higher_is_better),
           "unit": unit, "protocol": protocol or {}, "samples": samples or {}, "warnings": list(warnings or [])}
    rec.update(extra)
    return rec


def not_available(reason: str, higher_is_better: bool, unit: str = "", protocol: dict[str, Any] | None = None,
                  samples: dict[str, int] | None = None, **extra: Any) -> dict[str, Any]:
    """A metric that could not be computed, with the reason (shown as an n/a footnote in tables)."""
    rec = {"value": None, "available": False, "reason": str(reason), "higher_is_better": bool(higher_is_better),
           "unit": unit, "protocol": protocol or {}, "samples": samples or {}, "warnings": []}
    rec.update(extra)
    return rec
