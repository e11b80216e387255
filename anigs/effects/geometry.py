"""3D cues of effect detection, per Gaussian of the fitted model, and their per-pixel renders.

- up direction and ground plane (:func:`scene_ground`, via :func:`anigs.geometry.ground.ground_plane`);
- local shape of the Gaussian centres (:func:`local_shape`): PCA of the neighbours within a
  radius gives the surface variation ``l3 / (l1 + l2 + l3)`` (0 on a plane, 1/3 isotropic) and
  ``|normal . up|`` (1 on floors and water, 0 on walls and pictures);
- multi-view colour spread (:func:`colour_spread`): how much the photos disagree on the colour
  of a Gaussian's centre (reflections change with the viewpoint; diffuse surfaces do not);
- :func:`render_features`: up to 3 per-Gaussian features rendered as per-pixel maps.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.effects.cues import LUMA_WEIGHTS
from anigs.gaussians import Gaussians
from anigs.geometry import estimate_up
from anigs.render.visibility import VisibilityConfig, frustum_subset, project_to_pixels, render_inputs, visible_depth
from anigs.geometry.ground import GroundPlane, ground_plane
from anigs.render import rasterize

log = logging.getLogger("anigs.effects")

#: a render shows what makes at least this share of a pixel: its alpha, or its alpha-normalised feature (fraction)
SHOWN = 0.5
MAX_BELOW = 0.1  # by default a ground has at most this share of the Gaussians clearly under it (fraction)
#: a Gaussian lies clearly under the ground deeper than this x the cameras' height (or the layer, when deeper)
CLEARLY_BELOW = 0.1
SEEN_MIN_PIXELS = 100  # the seen ground sets the cut from this many pixels under the plane, all photos together (px)
MIN_NEIGHBOURS = 4  # a local shape needs this many neighbours; with fewer: isotropic, half up (count)
FEW_UPNESS = 0.5  # the |normal . up| given to a centre with too few neighbours (neither floor nor wall)
SPREAD_FLOOR = 0.05  # the colour spread is std / (mean + this): dark pixels' noise is no spread (luminance, 0..1)


@dataclass
class Ground:
    """The ground plane when it could be found, and why not otherwise (with the untrusted ``estimate``)."""

    plane: GroundPlane | None
    up: np.ndarray
    support: float = 0.0  # share of the Gaussians lying on the plane
    note: str = ""
    cut: float = 0.0      # seen surfaces lower than this above the plane are ground (:func:`seen_ground_cut`; 0: unset)
    #: the lowest dense layer when it is not trusted as the ground (``plane`` None): the rules measure heights (how
    #: high a crown is) from it all the same, so every rule runs on every capture; grass and water need ``plane``
    estimate: GroundPlane | None = None

    @property
    def reference(self) -> GroundPlane | None:
        """The plane the rules measure heights from: the ground, else the untrusted lowest dense layer."""
        return self.plane if self.plane is not None else self.estimate

    def cut_height(self) -> float:
        """Height above the plane below which a seen surface is ground (``cut``, else the plane's own)."""
        if self.plane is None:
            raise ValueError("Ground.cut_height: no ground plane")
        return float(self.cut) if self.cut > 0 else float(self.plane.cut_height())

    def to_dict(self) -> dict:
        return {"found": self.plane is not None, "up": self.up.tolist(), "support": round(self.support, 4),
                "note": self.note, **({"plane": self.plane.to_dict(), "cut": round(self.cut_height(), 4)}
                                      if self.plane is not None else {}),
                **({"estimate": self.estimate.to_dict()} if self.plane is None and self.estimate is not None else {})}


def world_up(cameras: Sequence[Camera], mode: str = "z", points: np.ndarray | None = None) -> np.ndarray:
    """Up [3]: +z (the SfM stage writes z-up), or with ``auto`` the capture's estimated up
    (:func:`anigs.geometry.estimate_up`: camera axes, photo orientation and the points' planes)."""
    if mode == "z":
        return np.array([0.0, 0.0, 1.0])
    return estimate_up(cameras, points).up


def scene_ground(means: np.ndarray, cameras: Sequence[Camera], up: np.ndarray, margin: float,
                 min_support: float, max_below: float = MAX_BELOW) -> Ground:
    """Ground plane of ``means`` [N,3] along ``up``; ``plane`` is None (with a note) when the cameras
    are not above it, fewer than ``min_support`` of the Gaussians lie within its layer, or more than
    ``max_below`` lie clearly under it (a close-up without visible ground)."""
    try:
        plane = ground_plane(means, up, cameras, margin=margin)
    except ValueError as err:
        return Ground(None, up, 0.0, f"no ground plane ({err}): no grass or water is looked for, and the rules that "
                                     "measure heights (sunlit leaves high in a crown) find none")
    h = means @ plane.normal - plane.offset
    band = max(plane.cut_height(), 1e-9)
    support = float((np.abs(h) <= band).mean())
    if support < min_support:
        return Ground(None, up, support, f"ground uncertain: only {100 * support:.1f}% of the Gaussians lie on "
                                         f"the lowest dense layer (needs {100 * min_support:.1f}%), so no grass or "
                                         "water is looked for; the rules measure heights from that layer", estimate=plane)
    below = float((h < -max(band, CLEARLY_BELOW * plane.camera_height)).mean())
    if below > max_below:  # nothing real lies under the ground: this layer is not it
        return Ground(None, up, support, f"ground uncertain: {100 * below:.0f}% of the Gaussians lie under the "
                                         f"lowest dense layer (at most {100 * max_below:.0f}% allowed), so no grass or "
                                         "water is looked for; the rules measure heights from that layer", estimate=plane)
    return Ground(plane, up, support, "")


def seen_ground_cut(plane: GroundPlane, heights: Sequence[np.ndarray], quantile: float,
                    min_pixels: int = SEEN_MIN_PIXELS) -> float:
    """Height below which a seen surface is ground: the ``quantile`` of how deep the photos see
    surfaces under the plane (``heights`` [H,W] per photo, nan where nothing is seen), mirrored
    upwards; between ``plane.min_height`` and ``plane.cut_height()``.

    ``plane.layer`` measures the scatter of all the ground's centres, hidden ones included: a
    fitted ground keeps a tail of Gaussians deep under its surface that no ray reaches, and that
    tail can put the cut above the grass and flower beds. What the photos see of the ground
    scatters about the plane as much above as below it, and only the ground is seen below it,
    so the seen depths under the plane measure how high the seen ground reaches.
    """
    hi = plane.cut_height()
    below = [-h[np.isfinite(h) & (h < 0)] for h in heights]
    below = np.concatenate(below) if below else np.zeros(0)
    if len(below) < min_pixels:
        return float(hi)
    return float(np.clip(np.quantile(below, quantile), plane.min_height, hi))


def local_shape(means: np.ndarray, up: np.ndarray, radius: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Surface variation [N] and ``|normal . up|`` [N] of each centre's neighbourhood (<= ``k``
    neighbours within ``radius``; fewer than ``MIN_NEIGHBOURS``: variation 1/3, upness ``FEW_UPNESS``)."""
    from scipy.spatial import cKDTree

    n = len(means)
    k = int(min(k, n))
    dist, idx = cKDTree(means).query(means, k=k, distance_upper_bound=radius)
    dist, idx = np.asarray(dist).reshape(n, k), np.asarray(idx).reshape(n, k)
    valid = np.isfinite(dist)
    cnt = valid.sum(1)
    safe = np.where(valid, idx, np.arange(n)[:, None])
    nb = means[safe]                                                   # [N,k,3]
    w = valid[..., None].astype(np.float64)
    mu = (nb * w).sum(1) / np.maximum(cnt, 1)[:, None]
    d = (nb - mu[:, None]) * w
    cov = np.einsum("nki,nkj->nij", d, d) / np.maximum(cnt, 1)[:, None, None]
    evals, evecs = np.linalg.eigh(cov)                                 # ascending
    variation = evals[:, 0] / np.maximum(evals.sum(1), 1e-18)
    upness = np.abs(evecs[:, :, 0] @ up)
    few = cnt < MIN_NEIGHBOURS
    variation[few], upness[few] = 1.0 / 3.0, FEW_UPNESS
    return variation, upness


def colour_spread(g: Gaussians, photos: Sequence[np.ndarray], cameras: Sequence[Camera],
                  depths: Sequence[np.ndarray]) -> np.ndarray:
    """Relative spread [N] of the photos' luminance at each visible centre: std / (mean + ``SPREAD_FLOOR``);
    0 for Gaussians seen by fewer than 2 photos."""
    means = g.means.detach().double().numpy()
    max_scale = g.scales.detach().max(1).values.double().numpy()
    s1 = np.zeros(len(means))
    s2 = np.zeros(len(means))
    cnt = np.zeros(len(means))
    vis = VisibilityConfig(mode="depth")
    for img, cam, depth in zip(photos, cameras, depths):
        seen = visible_depth(means, cam, depth, None, max_scale, vis)
        _, px, py, _ = project_to_pixels(means, cam, vis.near)
        lum = img[py, px] @ np.array(LUMA_WEIGHTS)
        s1 += np.where(seen, lum, 0.0)
        s2 += np.where(seen, lum * lum, 0.0)
        cnt += seen
    mean = s1 / np.maximum(cnt, 1)
    std = np.sqrt(np.maximum(s2 / np.maximum(cnt, 1) - mean * mean, 0.0))
    return np.where(cnt >= 2, std / (mean + SPREAD_FLOOR), 0.0)


def render_features(g: Gaussians, features: np.ndarray, cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render per-Gaussian ``features`` [N,C<=3] at ``cam``: (maps [H,W,C] (alpha-normalised),
    alpha [H,W], depth [H,W])."""
    features = np.asarray(features, np.float32)
    c = features.shape[1]
    if c > 3:
        raise ValueError(f"render_features: at most 3 channels per pass, got {c}")
    idx = frustum_subset(g, cam)
    cols = torch.zeros(len(idx), 3)
    cols[:, :c] = torch.from_numpy(features[idx.numpy()])
    with torch.no_grad():
        rgb, alpha, meta = rasterize(*render_inputs(g, idx), cols, cam.torch_viewmat(), cam.torch_K(),
                                     cam.width, cam.height)
    a = alpha.numpy()
    maps = rgb.numpy()[..., :c] / np.maximum(a, 1e-6)[..., None]
    return maps, a, meta["depth"].numpy()
