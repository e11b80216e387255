"""One round's model update as the ``update`` stage runs it (:mod:`anigs.stages.update`): the SDS term
of its video prior (:func:`sds_term`) and the ``update.json`` record of its result (:func:`round_record`).
The training itself: :func:`anigs.animate.update.run_update`."""
from __future__ import annotations

from typing import Any

from anigs.animate.config import UpdateConfig
from anigs.animate.losses import prior_sds_hook
from anigs.refine.prior import get_prior


def sds_term(cfg: UpdateConfig, prior: str | None, prior_params: dict[str, Any], prompt: str | None):
    """The SDS hook of ``lambda_sds > 0`` from the video prior ``prior`` (its config section
    ``prior_params``) and the text prompt; None when the config has no SDS term."""
    if not cfg.lambda_sds > 0:
        return None
    if not prior:
        raise ValueError("update: lambda_sds > 0 needs --prior (a video prior with a score, e.g. ltx)")

    return prior_sds_hook(get_prior(prior, prior_params), prompt or "", cfg.sds_frames)


def round_record(result, cfg: UpdateConfig, contained: dict | None) -> dict[str, Any]:
    """``update.json``: steps, timing, the loss history and the config of ``result`` (a
    :func:`~anigs.animate.update.run_update` result), and the containment counts when it was contained."""
    d = result.deformation
    info = {"steps": result.steps, "seconds": result.seconds, "skipped": result.skipped, "num_dynamic": d.num_dynamic,
            "num_bases": d.num_bases, "num_frames": d.num_frames, "history": result.history, "config": cfg.to_dict()}
    if contained is not None:
        info["containment"] = contained
    return info
