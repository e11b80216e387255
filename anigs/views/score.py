"""Score the candidate locations (ROI Gaussians their panorama sees) and choose the queue's
locations among them (farthest-point sampling weighted by the scores, counter-clockwise order)."""
from __future__ import annotations

import logging

import numpy as np

from anigs.gaussians import Gaussians
from anigs.geometry import horizontal_basis
from anigs.render.visibility import VisibilityConfig
from anigs.views.candidates import azimuth_deg, ccw_order, farthest_point_order, roi_azimuth, score_candidate
from anigs.views.config import ViewsConfig
from anigs.views.policy import LayoutPolicy

log = logging.getLogger("anigs.views")


def score_candidates(g: Gaussians, cand: np.ndarray, cand_fwd: np.ndarray, roi_idx: np.ndarray,
                     centroid: np.ndarray, up: np.ndarray, policy: LayoutPolicy, cfg: ViewsConfig,
                     vcfg: VisibilityConfig) -> tuple[np.ndarray, np.ndarray]:
    """(heading [M] deg, bool [M,R] ROI Gaussians each candidate's views would see).

    The heading is fixed by ``policy.forward`` (``centroid``: towards the ROI centroid,
    ``camera``: the capture camera's forward) or searched (``best``: :func:`score_candidate`).
    """
    heading = np.zeros(len(cand))
    cand_seen = np.zeros((len(cand), len(roi_idx)), dtype=bool)
    for m, pos in enumerate(cand):
        fixed = None
        if policy.forward == "centroid":
            az = roi_azimuth(pos, centroid, up)
            fixed = 0.0 if az is None else az
        elif policy.forward == "camera":
            fixed = float(azimuth_deg(cand_fwd[m], up))
        heading[m], cand_seen[m] = score_candidate(g, pos, roi_idx, up, cfg, vcfg, fixed)
    return heading, cand_seen


def choose_locations(cand: np.ndarray, cand_vis: np.ndarray, centroid: np.ndarray, up: np.ndarray,
                     cfg: ViewsConfig) -> tuple[list[int], list[int]]:
    """(chosen, extra) candidate indices: ``cfg.num_locations`` by farthest-point sampling from the
    best-seeing candidate (weighted by ``cand_vis`` [M] to ``cfg.visibility_power``), ordered
    counter-clockwise about the ROI centroid; then up to ``cfg.extra_locations`` more in sampling
    order (for directions no chosen location can place)."""
    start = int(np.argmax(cand_vis))
    n_extra = min(cfg.extra_locations, len(cand) - cfg.num_locations)
    fps = farthest_point_order(cand, cand_vis, cfg.num_locations + n_extra, start, cfg.visibility_power)
    chosen, extra = fps[:cfg.num_locations], fps[cfg.num_locations:]
    e1, e2 = horizontal_basis(up)
    flat = lambda p: np.stack([p @ e1, p @ e2], -1)  # noqa: E731
    order = ccw_order(flat(cand[chosen]), flat(centroid), first=0)
    return [chosen[i] for i in order], extra
