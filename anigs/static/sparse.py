"""Weight-free help for sparse captures (``static.sparse``) that the fit's set-up and loop call: the
start's points beyond SfM's (pairs of training photos, far points) and DropGaussian's per-step factors.
The warp loss is :mod:`anigs.static.warp`; the pair points :mod:`anigs.static.pair_points`."""
from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.static.far import far_points
from anigs.static.pair_points import PairPoints, pair_points
from anigs.static.stereo_points import stereo_points

if TYPE_CHECKING:
    from anigs.static.config import StaticConfig

log = logging.getLogger("anigs.static.fit")


def added_points(cfg: "StaticConfig", pts: np.ndarray, cols: np.ndarray, train_imgs: list[torch.Tensor],
                  train_cams: list[Camera], random_bg: bool
                  ) -> tuple[tuple[np.ndarray, np.ndarray] | None, PairPoints | None, int]:
    """The start's points beyond SfM's, for a fit on photos (random backgrounds): points from pairs of
    training photos (``static.sparse.pair_points``) and far points where the photos show what no point
    explains. Returns ((points [P,3], colours [P,3]) with SfM's first, or None when nothing was added;
    the pair points' record or None; the number of far points)."""
    photos = [im.cpu().numpy() for im in train_imgs]
    paired = None
    budget = int(cfg.sparse.pair_share * cfg.densify.max_gaussians)
    if cfg.sparse.pair_points and random_bg:  # photos only, as the far points
        paired = pair_points(photos, train_cams, cfg.sparse.pair_neighbours, within=pts, max_points=budget)
    elif cfg.sparse.stereo_points and random_bg:
        paired = stereo_points(photos, train_cams, within=pts, max_points=budget)
    if paired is not None:
        pts, cols = np.concatenate([pts, paired.xyz]), np.concatenate([cols, paired.rgb])
    # far points are for photos (random backgrounds); a fixed background is the far field itself (a
    # synthetic scene's sky: far points behind its sparsely triangulated tree crowns cost the demo 0.3-0.5 dB)
    fpts, fcols = far_points(pts, train_cams, photos, None,
                             int(cfg.far_share * cfg.densify.max_gaussians) if random_bg else 0)
    if len(fpts):
        log.info("static fit: %d far points where the photos show what SfM did not triangulate", len(fpts))
    if not len(fpts) and paired is None:
        return None, None, 0
    return (np.concatenate([pts, fpts]), np.concatenate([cols, fcols])), paired, len(fpts)


def dropout(n: int, rate: float, gen: torch.Generator, device: torch.device) -> torch.Tensor | None:
    """DropGaussian's factors [N] for one step: 0 for a Gaussian left out (probability ``rate``), else
    1 / (1 - rate), drawn from ``gen``; None when ``rate`` is 0 (nothing drawn: the fit is as without it)."""
    if rate <= 0:
        return None
    kept = torch.rand(n, generator=gen) >= rate
    return (kept.float() / (1.0 - rate)).to(device)
