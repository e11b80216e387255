"""Video priors: one interface (:class:`VideoPrior`), a backend per file, chosen by name.

- ``procedural`` (default): stochastic motion textures per effect type, offline, CPU.
- ``ltx``: LTX-Video through diffusers with weights from a local folder (GPU; CPU for tests).
"""
from __future__ import annotations

from typing import Any, Mapping

from anigs.refine.prior.base import MaskLike, VideoPrior

PRIORS = ("procedural", "ltx")


def get_prior(name: str, cfg: Mapping[str, Any] | None = None) -> VideoPrior:
    """Build the prior ``name`` from its config section (a dict; unknown keys are rejected)."""
    if name == "procedural":
        from anigs.refine.prior.procedural import ProceduralPrior

        return ProceduralPrior(cfg)
    if name == "ltx":
        from anigs.refine.prior.ltx import LTXPrior

        return LTXPrior(cfg)
    raise ValueError(f"unknown video prior {name!r}; available: {list(PRIORS)}")


__all__ = ["PRIORS", "MaskLike", "VideoPrior", "get_prior"]
