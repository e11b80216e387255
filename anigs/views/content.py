"""What a view would show: the share of its pixels that reconstructed content dominates.

The coverage rule (:func:`anigs.views.coverage.scene_coverage`) counts alpha from Gaussians seen
by enough photos. Long blurry needles across the sky and the smooth blobs around a close-up are
seen by every photo, so views of empty sky pass it. The content figure counts a pixel only when
it is dominated by *sharp* Gaussians (:func:`sharp_gaussians`), each of which must be

- **resolved by photos**: its largest standard deviation, projected into a capture photo where
  it is visible (blending weight >= ``min_weight`` pixels), is at most ``sharp_fraction`` of the
  photo's width in at
  least ``min_sharp_observations`` photos;
- **not far larger than its neighbours**: its largest scale is at most ``footprint_ratio``
  times the median largest scale of its ``neighbours`` nearest Gaussians (same depth, so the
  same ratio of screen footprints);
- **near the SfM points**: its centre lies within ``near_points`` x the local spacing of the
  nearest SfM point (that point's distance to its 8th nearest point; skipped without points).

The three tests above do not depend on the view. A fourth does: **sampled finely enough by a
photo**. A view closer to the content than any photo magnifies what the photos resolved: a
Gaussian sized to one photo pixel spans several of the view's pixels, and the view shows a
smooth blur. Each Gaussian's *photo footprint* is the finest pixel footprint among the photos
it is visible in (its centre's depth over the photo's focal length: world units per pixel,
:func:`photo_footprints`); the view's footprint at the same Gaussian is its depth in the view
over the view's focal length. The Gaussian counts for the view only when the photo footprint
is at most ``max_sampling_ratio`` times the view's (the view samples it at most that many times
finer than the best photo; 0: the term is off).

:func:`content_fraction` renders the view with every Gaussian and counts the pixels whose
alpha is >= ``alpha`` and whose alpha the sharp Gaussians that the view does not magnify carry
>= half of (the masks stage's dominance rule, :func:`anigs.render.labels.label_masks`).

:func:`edge_share` is the image figure of the issue that asked for this: the share of pixels
within ``radius`` px of an edge (absolute 4-neighbour Laplacian of the grey image, 0-255, above
``threshold``), computed on the view's colour render. It is recorded for each view.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Protocol, Sequence

import cv2
import numpy as np
import torch

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render import rasterize
from anigs.render.labels import label_masks
from anigs.render.visibility import blend_weights, frustum_subset, render_inputs

log = logging.getLogger("anigs.views")

EDGE_THRESHOLD = 6.0   # |Laplacian| of the grey image (0-255) that marks an edge
EDGE_RADIUS = 4        # a pixel is near an edge within this many pixels


FOOTPRINT_NEIGHBOURS = 16  # a Gaussian's footprint is compared with the median of this many nearest neighbours'


@dataclass
class ContentRule:
    """Parameters of the sharp-Gaussian test and the content figure, derived from :class:`ViewsConfig`
    (``ViewsConfig.content_rule()``: the defaults live there alone)."""

    min_content: float                # a view is kept when >= this share of its pixels shows sharp content
    sharp_fraction: float             # a photo resolves a Gaussian when its largest std dev spans <= this x its width
    min_sharp_observations: int       # ... in at least this many photos
    footprint_ratio: float            # largest scale <= this x the median of its FOOTPRINT_NEIGHBOURS neighbours'
    near_points: float                # centre within this x the local SfM point spacing of a point (no points: skipped)
    alpha: float                      # a content pixel has accumulated alpha >= this
    min_weight: float                 # visibility in a photo: blending weight >= this (pixels)
    max_sampling_ratio: float         # a Gaussian counts for a view when its best photo's pixel footprint <= this x the view's (0: off)
    min_motion_sharpness: float       # the moving region's band sharpness >= this x the best photo's (0: recorded only)
    max_unobserved: float             # share of pixels of alpha < 0.5 a view may show (1: recorded only)


@dataclass
class SharpSet:
    """Per-Gaussian result of :func:`sharp_gaussians` (N = number of Gaussians)."""

    sharp: np.ndarray                 # bool [N]
    observations: np.ndarray          # int [N] photos the Gaussian is visible in
    sharp_observations: np.ndarray    # int [N] photos that resolve it
    footprint_ok: np.ndarray          # bool [N]
    near_points: np.ndarray           # bool [N] (all True without points)
    photo_footprint: np.ndarray | None = None  # float [N] finest pixel footprint (world units / px) of a photo it is visible in; inf: none
    summary: dict[str, Any] = field(default_factory=dict)


def projected_sigma_px(g: Gaussians, cam: Camera) -> np.ndarray:
    """Largest standard deviation of each Gaussian projected at its centre's depth, in pixels,
    float [N] (inf behind the camera)."""
    means = g.means.detach().double().numpy()
    s = g.scales.detach().double().numpy().max(1)
    pc = means @ cam.R.T + cam.t
    z = pc[:, 2]
    f = float(max(cam.K[0, 0], cam.K[1, 1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(z > 1e-6, s * f / np.maximum(z, 1e-6), np.inf)


def pixel_footprint(g: Gaussians, cam: Camera) -> np.ndarray:
    """World size of one of ``cam``'s pixels at each Gaussian's centre (its depth over the focal
    length), float [N]; inf behind the camera."""
    means = g.means.detach().double().numpy()
    z = means @ cam.R[2] + cam.t[2]
    f = float(max(cam.K[0, 0], cam.K[1, 1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(z > 1e-6, z / f, np.inf)


def photo_footprints(g: Gaussians, cameras: Sequence[Camera], min_weight: float = 0.05) -> np.ndarray:
    """float [N]: the finest :func:`pixel_footprint` of each Gaussian among the ``cameras`` it is
    visible in (summed blending weight >= ``min_weight`` pixels); inf where none sees it."""
    return observation_and_sharp_counts(g, cameras, 1.0, min_weight)[2]


def observation_and_sharp_counts(g: Gaussians, cameras: Sequence[Camera], sharp_fraction: float,
                                 min_weight: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(photos each Gaussian is visible in, photos that resolve it): int [N] each, and its finest
    pixel footprint among the photos it is visible in (float [N], inf: none; :func:`photo_footprints`).

    Visible: summed blending weight >= ``min_weight`` pixels (the ``weight`` visibility test);
    resolved: visible and :func:`projected_sigma_px` <= ``sharp_fraction`` x the photo's width.
    """
    obs = np.zeros(g.num, np.int64)
    sharp = np.zeros(g.num, np.int64)
    finest = np.full(g.num, np.inf)
    for cam in cameras:
        total, _ = blend_weights(g, cam)
        seen = total >= min_weight
        obs += seen
        sharp += seen & (projected_sigma_px(g, cam) <= sharp_fraction * cam.width)
        finest = np.where(seen, np.minimum(finest, pixel_footprint(g, cam)), finest)
    return obs, sharp, finest


def footprint_ratio(g: Gaussians, neighbours: int = 16) -> np.ndarray:
    """float [N]: each Gaussian's largest scale over the median largest scale of its
    ``neighbours`` nearest Gaussians (by centre; 1 when there are no neighbours)."""
    from scipy.spatial import cKDTree

    means = g.means.detach().double().numpy()
    s = g.scales.detach().double().numpy().max(1)
    k = min(neighbours, g.num - 1)
    if k < 1:
        return np.ones(g.num)
    _, idx = cKDTree(means).query(means, k=k + 1)
    med = np.median(s[idx[:, 1:]], axis=1)
    return s / np.maximum(med, 1e-12)


def near_points_mask(g: Gaussians, points: np.ndarray | None, factor: float, k: int = 8) -> np.ndarray:
    """bool [N]: centre within ``factor`` x the local spacing of the nearest SfM point [P,3] (its
    distance to its ``k``-th nearest point); all True without points."""
    if points is None or len(points) == 0:
        return np.ones(g.num, bool)
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64).reshape(-1, 3)
    tree = cKDTree(pts)
    kk = min(k, len(pts) - 1)
    spacing = tree.query(pts, k=kk + 1)[0][:, -1] if kk >= 1 else np.full(len(pts), np.inf)
    d, i = tree.query(g.means.detach().double().numpy(), k=1)
    return d <= factor * spacing[i]


def sharp_gaussians(g: Gaussians, cameras: Sequence[Camera], rule: ContentRule,
                    points: np.ndarray | None = None) -> SharpSet:
    """The Gaussians that reconstructed content is made of (see the module docstring)."""
    obs, sobs, finest = observation_and_sharp_counts(g, cameras, rule.sharp_fraction, rule.min_weight)
    ratio = footprint_ratio(g, FOOTPRINT_NEIGHBOURS)
    foot = ratio <= rule.footprint_ratio
    near = near_points_mask(g, points, rule.near_points)
    resolved = sobs >= rule.min_sharp_observations
    sharp = resolved & foot & near
    n = max(g.num, 1)
    summary = {"sharp": int(sharp.sum()), "of": int(g.num), "resolved": int(resolved.sum()),
               "footprint_ok": int(foot.sum()), "near_points": None if points is None else int(near.sum())}
    log.info("views: %d of %d Gaussians are sharp (%.1f%%): resolved by >= %d photos %.1f%%, footprint <= %gx "
             "neighbours' %.1f%%, near SfM points %s", summary["sharp"], g.num, 100 * sharp.sum() / n,
             rule.min_sharp_observations, 100 * resolved.sum() / n, rule.footprint_ratio, 100 * foot.sum() / n,
             "n/a" if points is None else f"{100 * near.sum() / n:.1f}%")
    return SharpSet(sharp, obs, sobs, foot, near, finest, summary)


def magnified(g: Gaussians, photo_footprint: np.ndarray, cam: Camera, max_ratio: float) -> np.ndarray:
    """bool [N]: the Gaussians that ``cam`` samples more than ``max_ratio`` times finer than the
    best photo that sees them (``photo_footprint`` [N] > ``max_ratio`` x ``cam``'s
    :func:`pixel_footprint`); none when ``max_ratio`` is 0. Gaussians behind ``cam`` are never
    magnified (it does not render them)."""
    if max_ratio <= 0:
        return np.zeros(g.num, bool)
    view = pixel_footprint(g, cam)
    return np.isfinite(view) & (np.asarray(photo_footprint) > max_ratio * view)


def content_masks(g: Gaussians, sharp: np.ndarray, cam: Camera, alpha: float = 0.5,
                  photo_footprint: np.ndarray | None = None, max_sampling_ratio: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(content, sharp) bool [H,W] of ``cam`` in one render: pixels with alpha >= ``alpha`` of
    which the ``sharp`` [N] Gaussians that ``cam`` does not magnify (:func:`magnified`, with
    ``photo_footprint`` [N]; without it nothing is magnified) carry >= half; and the same
    without the magnification term."""
    sharp = np.asarray(sharp, bool)
    empty = np.zeros((cam.height, cam.width), bool)
    if not sharp.any():
        return empty, empty
    far = np.zeros(g.num, bool) if photo_footprint is None else magnified(g, photo_footprint, cam, max_sampling_ratio)
    labels = np.where(sharp, np.where(far, 1, 2), 0).astype(np.int64)  # 0 not sharp, 1 magnified, 2 content
    m = label_masks(g.detach(), labels, {"content": [2], "sharp": [1, 2]}, cam, 0.5, alpha)
    return m["content"], m["sharp"]


def content_fraction(g: Gaussians, sharp: np.ndarray, cam: Camera, alpha: float = 0.5,
                     photo_footprint: np.ndarray | None = None, max_sampling_ratio: float = 0.0) -> float:
    """Share of ``cam``'s pixels with alpha >= ``alpha`` of which the ``sharp`` [N] Gaussians carry
    >= half, leaving out those ``cam`` magnifies more than ``max_sampling_ratio`` x the best
    photo's sampling (``photo_footprint`` [N]; :func:`content_masks`)."""
    return float(content_masks(g, sharp, cam, alpha, photo_footprint, max_sampling_ratio)[0].mean())


def render_rgb(g: Gaussians, cam: Camera, background: Sequence[float]) -> np.ndarray:
    """Colour render float [H,W,3] in [0,1] of ``g`` from ``cam`` onto ``background``."""
    idx = frustum_subset(g, cam)
    bg = torch.tensor([float(x) for x in background], dtype=torch.float32)
    if len(idx) == 0:
        return np.broadcast_to(bg.numpy(), (cam.height, cam.width, 3)).copy()
    deg = g.sh_degree
    with torch.no_grad():
        rgb, _, _ = rasterize(*render_inputs(g, idx), g.sh.detach().float().cpu()[idx], cam.torch_viewmat(),
                              cam.torch_K(), cam.width, cam.height, sh_degree=deg, background=bg)
    return rgb.clamp(0, 1).numpy()


def edge_share(image: np.ndarray, threshold: float = EDGE_THRESHOLD, radius: int = EDGE_RADIUS) -> float:
    """Share of pixels within ``radius`` px of an edge: |4-neighbour Laplacian| of the grey
    image (0-255) > ``threshold``. ``image``: [H,W,3] or [H,W], float in [0,1] or uint8."""
    a = np.asarray(image)
    a = a.astype(np.float32) * (255.0 if a.dtype != np.uint8 else 1.0)
    grey = a if a.ndim == 2 else a[..., :3] @ np.array([0.299, 0.587, 0.114], np.float32)
    lap = np.abs(cv2.Laplacian(grey.astype(np.float32), cv2.CV_32F, ksize=1))
    edges = (lap > threshold).astype(np.uint8)
    if radius > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        edges = cv2.dilate(edges, k)
    return float(edges.mean())


class MotionFigure(Protocol):
    """What :class:`ContentCheck` asks of its ``motion`` figure (:class:`anigs.views.motion.MotionSharpness`,
    which builds on this module: declared here so that this module does not import it)."""

    def measure(self, cam: Camera, rgb: np.ndarray) -> dict[str, Any]: ...

    def to_json(self) -> dict[str, Any]: ...


class ContentCheck:
    """The content test of candidate directions: :func:`content_fraction` (gated at
    ``rule.min_content``), :func:`edge_share` (gated at ``min_edge_share``; 0 records it only) and,
    with ``motion`` (:class:`anigs.views.motion.MotionSharpness`), the moving region's sharpness
    against the photos' (gated at ``rule.min_motion_sharpness``) and the unobserved pixels (gated at
    ``rule.max_unobserved``)."""

    def __init__(self, g: Gaussians, sharp: SharpSet, rule: ContentRule, background: Sequence[float],
                 min_edge_share: float = 0.0, motion: MotionFigure | None = None):
        self.g, self.sharp, self.rule = g, sharp, rule
        self.background, self.min_edge_share = list(background), float(min_edge_share)
        self.motion = motion

    def measure(self, cam: Camera) -> dict[str, Any]:
        """{"content": ..., "magnified": ..., "edge_share": ...} of a view: ``magnified`` is the share
        of its pixels that sharp Gaussians dominate but that the view magnifies beyond
        ``max_sampling_ratio`` (left out of ``content``); with ``motion``, also its figures
        (:meth:`anigs.views.motion.MotionSharpness.measure`)."""
        content, sharp = content_masks(self.g, self.sharp.sharp, cam, self.rule.alpha, self.sharp.photo_footprint,
                                       self.rule.max_sampling_ratio)
        rgb = render_rgb(self.g, cam, self.background)
        fig: dict[str, Any] = {"content": float(content.mean()), "magnified": float((sharp & ~content).mean()),
                               "edge_share": edge_share(rgb)}
        if self.motion is not None:
            fig.update(self.motion.measure(cam, rgb))
        return fig

    def failure(self, fig: dict[str, float]) -> str | None:
        """Why a view with figures ``fig`` fails (None: it passes)."""
        why = []
        if fig["content"] < self.rule.min_content:
            why.append(f"content {fig['content']:.2f} < min_content {self.rule.min_content:g} (pixels dominated "
                       "by sharp Gaussians" + (f"; {fig['magnified']:.2f} of the view magnifies its sharp Gaussians > "
                                               f"max_sampling_ratio {self.rule.max_sampling_ratio:g} x the best photo's "
                                               "sampling" if fig.get("magnified", 0) > 0 else "") + ")")
        if fig["edge_share"] < self.min_edge_share:
            why.append(f"edge share {fig['edge_share']:.2f} < min_edge_share {self.min_edge_share:g}")
        ms = fig.get("motion_sharpness")
        if ms is not None and ms < self.rule.min_motion_sharpness:
            why.append(f"motion sharpness {ms:.2f} < min_motion_sharpness {self.rule.min_motion_sharpness:g}: the "
                       f"moving region is blurrier than photo {fig['motion_reference']} shows it (band sharpness "
                       f"{fig['motion_view']:.3f} vs {fig['motion_photo']:.3f} at the view's sampling)")
        if fig.get("unobserved", 0.0) > self.rule.max_unobserved:
            why.append(f"unobserved {fig['unobserved']:.3f} > max_unobserved {self.rule.max_unobserved:g} (pixels no "
                       "Gaussian covers show the background)")
        return "; ".join(why) or None

    def to_json(self) -> dict[str, Any]:
        """The rule as recorded in ``views.json`` (``content``)."""
        r = self.rule
        return {"min_content": r.min_content, "min_edge_share": self.min_edge_share, "sharp_fraction": r.sharp_fraction,
                "min_sharp_observations": r.min_sharp_observations, "footprint_ratio": r.footprint_ratio,
                "neighbours": FOOTPRINT_NEIGHBOURS, "near_points": r.near_points, "alpha": r.alpha,
                "max_sampling_ratio": r.max_sampling_ratio, "min_motion_sharpness": r.min_motion_sharpness,
                "max_unobserved": r.max_unobserved, "motion": None if self.motion is None else self.motion.to_json(),
                "edge": {"threshold": EDGE_THRESHOLD, "radius_px": EDGE_RADIUS, "background": self.background},
                "sharp_gaussians": self.sharp.summary,
                "definition": ("content: share of the view's pixels with alpha >= alpha of which sharp Gaussians "
                               "carry >= half; sharp: resolved (largest std dev <= sharp_fraction x its width) by >= "
                               "min_sharp_observations photos, largest scale <= footprint_ratio x the median of "
                               "its neighbours', within near_points x the local spacing of the nearest SfM point, "
                               "and not magnified by the view: the finest pixel footprint (depth / focal length) of a "
                               "photo it is visible in <= max_sampling_ratio x the view's at it (0: off); magnified: "
                               "share of pixels sharp Gaussians dominate that fail only that; edge_share: "
                               "share of the colour render within radius_px of |Laplacian(grey 0-255)| > threshold")}
