"""Which effect each dynamic Gaussian belongs to, and one mask per chosen effect for the
backends that give a single dynamic mask (vegetation, sam2)."""
from __future__ import annotations

import logging
from typing import Sequence

import numpy as np

from anigs.effects.config import REGIONS
from anigs.gaussians import Gaussians
from anigs.masks import Frame
from anigs.effects.labels import effect_label_ids, effect_labels
from anigs.masks.labels_backend import LabelsBackend

log = logging.getLogger("anigs.masks")


def label_dynamic(g: Gaussians, dyn: np.ndarray, chosen: Sequence[str], regions: np.ndarray) -> tuple[np.ndarray, dict]:
    """(int8 [N] effect labels of the dynamic set: 0 static, 1 + region index,
    :mod:`anigs.effects.labels`; their counts for ``masks.json``) from the effects stage's
    regions [N] of its ``chosen`` effects."""
    chosen_regions = sorted({effect_label_ids()[e] - 1 for e in chosen})
    labels, counts = effect_labels(dyn, regions, chosen_regions, g.means.detach().double().numpy())
    counts["per_region"] = {REGIONS[k - 1]: int((labels == k).sum()) for k in range(1, len(REGIONS) + 1)}
    log.info("masks: effect labels of the %d dynamic Gaussians: %s (%d from the effects stage's regions, %d from "
             "the nearest labelled one)", int(dyn.sum()), counts["per_region"], counts["from_regions"], counts["nearest"])
    return labels, counts


def add_effect_masks(g: Gaussians, labels: np.ndarray, chosen: Sequence[str], frames: Sequence[Frame],
                     results: list[dict], opts: dict) -> None:
    """Add to each view's ``results`` the render of each chosen effect's dynamic Gaussians (by their
    effect label), within the backend's mask."""
    ids = effect_label_ids()
    backend = LabelsBackend(g, labels.astype(np.int64), {e: [ids[e]] for e in chosen}, **opts)
    for fr, res in zip(frames, results):
        for e, m in backend(fr).items():
            if e != "dynamic":
                res[e] = m & res["dynamic"]
