"""Ground plane (:func:`estimate_ground`); the ground cue's plane with its floor and measured layer
(:class:`GroundPlane`, :func:`ground_plane`) and the height of each pixel's surface above it
(:func:`pixel_heights`)."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.geometry.basics import unit

log = logging.getLogger("anigs.geometry")


@dataclass
class GroundEstimate:
    """The estimated ground plane ``x . normal = offset`` (:func:`estimate_ground`).

    ``layer``: thickness of the reconstructed ground measured below the plane;
    ``camera_height``: median camera height above the plane (0 without cameras);
    ``ref``: the length ``min_height`` margins scale with (camera height, else the height range).
    """

    normal: np.ndarray
    offset: float
    layer: float
    camera_height: float
    ref: float
    method: str = "densest-layer"   # densest-layer | below-cameras | fallback
    fallback: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {"normal": [float(v) for v in self.normal], "offset": float(self.offset), "layer": float(self.layer),
                "camera_height": float(self.camera_height), "method": self.method, "fallback": self.fallback}


def _densest_layer(h: np.ndarray, lo: float, top: float, width: float) -> float:
    low = h[(h >= lo) & (h <= top)]
    if len(low) == 0:
        low = h
    hist, edges = np.histogram(low, bins=max(int((top - lo) / width), 1), range=(lo, max(top, lo + width)))
    k = int(np.argmax(hist))
    c = 0.5 * (edges[k] + edges[k + 1])
    near = h[np.abs(h - c) <= width]
    return float(near.mean()) if len(near) else float(c)


def estimate_ground(means: np.ndarray, up: np.ndarray, cameras: Sequence[Camera] = (), bins: int = 400,
                    layer_quantile: float = 0.97, layer_band: float = 0.5, min_below: int = 10) -> GroundEstimate:
    """Ground plane of points ``means`` [N,3] along ``up`` [3].

    The densest thin layer below the median height (histogram peak refined by the mean of the
    points within one bin). When cameras are given and are not above it, the search is
    repeated among the points below the lowest camera; with fewer than ``min_below`` such
    points the fallback plane lies one bin below the lowest point (a warning is logged).
    ``layer``: the ``layer_quantile`` quantile of the depths of the points within
    ``layer_band`` * ref below the plane (the scatter of a fitted ground).
    Raises only for bad arguments (fewer than 10 points, quantile outside (0, 1)).
    """
    up = unit(np.asarray(up, np.float64))
    h = np.asarray(means, np.float64) @ up
    if len(h) < 10:
        raise ValueError(f"estimate_ground: need >= 10 Gaussians, got {len(h)}")
    if not 0.0 < layer_quantile < 1.0:
        raise ValueError(f"estimate_ground: layer_quantile must be in (0, 1), got {layer_quantile}")
    lo, hi = np.percentile(h, [0.5, 99.5])
    med = float(np.median(h))
    width = max((hi - lo) / bins, 1e-9)
    offset = _densest_layer(h, lo, med, width)
    method, fallback = "densest-layer", False
    cam_h = 0.0
    if len(cameras):
        ch = np.array([c.center @ up for c in cameras])
        ref = float(np.median(ch - offset))
        if ref <= 0:
            below = h[h < ch.min() - width]
            if len(below) >= min_below:
                offset = _densest_layer(below, float(np.percentile(below, 0.5)), float(below.max()), width)
                method = "below-cameras"
                log.warning("estimate_ground: the densest layer (median camera height %.3g above it) is not below "
                            "the cameras; using the densest layer of the %d points below them", ref, len(below))
            else:
                offset = float(min(lo, ch.min()) - width)
                method, fallback = "fallback", True
                log.warning("estimate_ground: no ground below the cameras (%d points below the lowest camera); "
                            "fallback plane just below all content (the ground cue excludes nothing)", len(below))
            ref = float(np.median(ch - offset))
            if ref <= 0:  # cameras far below their own median: keep a positive reference length
                ref = float(max(hi - lo, width))
        cam_h = ref
    else:
        ref = float(hi - lo)
    depth_below = offset - h
    below = depth_below[(depth_below > 0) & (depth_below <= layer_band * ref)]
    layer = float(np.quantile(below, layer_quantile)) if len(below) >= 10 else 0.0
    return GroundEstimate(up, offset, layer, cam_h, ref, method, fallback)


@dataclass
class GroundPlane:
    """Ground plane ``x . normal = offset`` and the thickness of the reconstructed ground layer.

    ``min_height``: the fixed floor (``margin`` * camera height); ``layer``: how far the
    reconstructed ground scatters around the plane, measured below it (see
    :func:`estimate_ground`); ``camera_height``: median camera height above the plane (0 when
    unknown). Surfaces lower than :meth:`cut_height` above the plane are ground.
    """

    normal: np.ndarray
    offset: float
    min_height: float
    layer: float = 0.0
    camera_height: float = 0.0

    def cut_height(self, layer_scale: float = 1.0, max_fraction: float = 0.3) -> float:
        """Height below which a surface counts as ground: the larger of ``min_height`` and
        ``layer_scale`` * ``layer``, capped at ``max_fraction`` * camera height (when known).
        """
        h = max(self.min_height, layer_scale * self.layer)
        if self.camera_height > 0 and max_fraction > 0:
            h = min(h, max(self.min_height, max_fraction * self.camera_height))
        return float(h)

    def to_dict(self) -> dict:
        return {"normal": np.asarray(self.normal).tolist(), "offset": float(self.offset),
                "min_height": float(self.min_height), "layer": float(self.layer),
                "camera_height": float(self.camera_height)}


def ground_plane(means: np.ndarray, up: np.ndarray, cameras: Sequence[Camera] = (),
                 margin: float = 0.03, bins: int = 400, layer_quantile: float = 0.97,
                 layer_band: float = 0.5) -> GroundPlane:
    """Ground plane of Gaussian centres ``means`` [N,3] along ``up`` [3] (:func:`estimate_ground`), with
    the floor and layer the ground cues of the masks and effects use.

    The ground is the densest thin layer below the median height (a histogram peak, refined
    by the mean of the centres within one bin). ``min_height`` = ``margin`` * median camera
    height above it (or * the scene's height range when no cameras are given).

    ``layer``: the thickness of the reconstructed ground. A fitted ground is not a thin sheet:
    in poorly observed places its Gaussians scatter above and below the true surface, and a
    ray sees the top of that scatter, so a static lawn renders well above the plane. Nothing
    real lies under the ground, so the centres below the plane (within ``layer_band`` *
    camera height of it) measure that scatter; its ``layer_quantile`` quantile, mirrored
    upwards, is how high the ground layer reaches. On a clean reconstruction it is tiny and
    ``min_height`` rules.

    Cameras not above that layer (looking up at a building) or no ground below them (a
    close-up) no longer raise: :func:`estimate_ground` searches below the cameras or falls back to
    a plane under all content, and logs it.
    """
    gr = estimate_ground(means, up, cameras, bins=bins, layer_quantile=layer_quantile, layer_band=layer_band)
    return GroundPlane(gr.normal, gr.offset, margin * gr.ref, gr.layer, gr.camera_height)


def pixel_heights(depth: np.ndarray, cam: Camera, plane: GroundPlane) -> np.ndarray:
    """Height above ``plane`` [H,W] of the surface seen at each pixel (depth = camera z)."""
    h, w = depth.shape
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    Kinv = np.linalg.inv(cam.K)
    rays = np.stack([xs, ys, np.ones_like(xs)], -1) @ Kinv.T          # camera coords at z=1
    world_dirs = rays @ cam.R                                           # R^T applied per row
    pts = cam.center + world_dirs * depth[..., None]
    return pts @ plane.normal - plane.offset
