"""The static fit's starting state: the held-out split, Gaussians initialised from the SfM
points, the training parameter dict (and back to :class:`~anigs.gaussians.Gaussians`) and its
Adam optimizer."""
from __future__ import annotations

import logging

import numpy as np
import torch
from scipy.spatial import cKDTree

from anigs.gaussians import Gaussians

log = logging.getLogger("anigs.static.fit")


def split_holdout(n: int, every: int) -> tuple[list[int], list[int]]:
    """Indices (train, test): image i is held out when ``every > 0`` and ``i % every == 0``."""
    test = [i for i in range(n) if every > 0 and i % every == 0]
    train = [i for i in range(n) if i not in set(test)]
    if not train:
        raise ValueError(f"no training images left: {n} images with holdout_every={every}")
    return train, test


def init_gaussians(points: np.ndarray, colors: np.ndarray, extent: float, sh_degree: int = 3,
                   opacity: float = 0.1) -> Gaussians:
    """Isotropic Gaussians at SfM ``points`` [P,3] with ``colors`` [P,3] in [0,1].

    Exact duplicate points are merged (colours averaged). Scale = root mean square distance to
    the 3 nearest neighbours (scipy cKDTree), clamped to [1e-4, 1] x extent; a single point gets
    0.01 x extent.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    colors = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        raise ValueError("static fit: the SfM point cloud is empty; nothing to initialise from")
    if len(colors) != len(points):
        raise ValueError(f"static fit: {len(points)} points but {len(colors)} colours")
    finite = np.isfinite(points).all(1)
    if not finite.all():
        log.warning("dropping %d non-finite SfM points", int((~finite).sum()))
        points, colors = points[finite], colors[finite]
        if len(points) == 0:
            raise ValueError("static fit: every SfM point is non-finite")
    uniq, inverse = np.unique(points, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    if len(uniq) < len(points):
        log.info("merged %d duplicate SfM points", len(points) - len(uniq))
        summed = np.zeros((len(uniq), 3))
        np.add.at(summed, inverse, colors)
        colors = summed / np.bincount(inverse, minlength=len(uniq))[:, None]
        points = uniq
    n = len(points)
    if n == 1:
        dist = np.full(1, 0.01 * extent)
    else:
        k = min(3, n - 1)
        d, _ = cKDTree(points).query(points, k=k + 1)
        dist = np.sqrt((d[:, 1:] ** 2).mean(1))
    dist = np.clip(dist, 1e-4 * extent, extent)
    return Gaussians.from_points(torch.from_numpy(points).float(), torch.from_numpy(np.clip(colors, 0, 1)).float(),
                                 torch.from_numpy(dist).float(), opacity=opacity, sh_degree=sh_degree)


def to_params(g: Gaussians, device: torch.device) -> dict[str, torch.nn.Parameter]:
    P = lambda t: torch.nn.Parameter(t.detach().to(device).contiguous())
    return {"means": P(g.means), "quats": P(g.quats), "log_scales": P(g.log_scales),
            "opacity_logits": P(g.opacity_logits), "sh_dc": P(g.sh[:, :1]), "sh_rest": P(g.sh[:, 1:])}


def params_to_gaussians(params: dict[str, torch.Tensor]) -> Gaussians:
    """Detached CPU :class:`Gaussians` from the training parameter dict."""
    sh = torch.cat([params["sh_dc"], params["sh_rest"]], 1)
    g = Gaussians(params["means"], params["quats"], params["log_scales"], params["opacity_logits"], sh)
    return g.detach().to("cpu")


def make_optimizer(params: dict[str, torch.nn.Parameter], lr: dict[str, float]) -> torch.optim.Adam:
    """Adam with one group per parameter (``"name"`` = its key, learning rate ``lr[key]``), eps 1e-15.

    Fused (one kernel for all groups) where torch has it for the device, else foreach.
    """
    groups = [{"params": [params[k]], "lr": lr[k], "name": k} for k in params]
    dev = next(iter(params.values())).device
    if dev.type in ("cpu", "cuda"):
        try:
            return torch.optim.Adam(groups, lr=0.0, eps=1e-15, fused=True)
        except (RuntimeError, ValueError):  # an older torch or an unsupported dtype
            groups = [{"params": [params[k]], "lr": lr[k], "name": k} for k in params]
    return torch.optim.Adam(groups, lr=0.0, eps=1e-15, foreach=True)
