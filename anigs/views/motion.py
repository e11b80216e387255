"""How sharp a view shows the moving region, against how sharp the photos show it.

A view exists to show the motion. The content figure (:mod:`anigs.views.content`) counts
pixels of Gaussians that photos resolve, which a smear of large splats over half a frame of
sharp facade passes. This figure looks only at the **moving region** (the pixels the ROI
Gaussians dominate, the masks stage's rule) and compares the view's render there with the real
photo that shows the same Gaussians best:

- **Band sharpness** of an image region (:func:`band_sharpness`): the mean absolute difference
  of the grey image from its Gaussian blur at ``FINE_SIGMA`` px over the same at
  ``COARSE_SIGMA`` px, over the region's pixels. Fine detail over medium detail: a smear
  scores near 0, a sharp natural image 0.3-0.55. The ratio does not depend on contrast, and a
  natural image's spectrum makes it nearly independent of the image scale.
- **At the view's sampling**: a photo that sees the region k times finer than the view
  (``k`` = median over the shared moving Gaussians of the photo's pixel footprint over the
  view's, :func:`anigs.views.content.pixel_footprint`) is downsampled by k before it is
  measured, so that a view does not pass by showing less detail per pixel than the photo; a
  photo coarser than the view (k > 1: the view magnifies) is taken as it is, so magnified blur
  counts against the view.
- **Reference**: the photo that resolves the region best: among the photos that see at least
  ``REFERENCE_SHARE`` of the view's visible moving Gaussians and ``SIMILAR_SHARE`` of what the
  best-seeing photo sees (the same content), the one that samples them finest. The figure is
  ``motion_sharpness = view / reference``; a view below ``views.min_motion_sharpness`` shows the
  motion blurrier than the photos do.

Also per view: ``unobserved``, the share of pixels whose rendered alpha is < ``HOLE_ALPHA``,
where the background shows through because no Gaussian (no photo) covers them.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import cv2
import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.images import downscale, find_image, load_image_compact
from anigs.render.labels import render_effect_weights
from anigs.render.visibility import blend_weights
from anigs.views.content import pixel_footprint
from anigs.views.coverage import DYNAMIC_ALPHA, DYNAMIC_SHARE

log = logging.getLogger("anigs.views")

FINE_SIGMA = 1.0        # px: the fine band's blur
COARSE_SIGMA = 4.0      # px: the medium band's blur
REFERENCE_SHARE = 0.5   # a photo is a reference when it sees >= this share of the view's visible moving Gaussians
SIMILAR_SHARE = 0.8     # ... and >= this share of what the photo that sees most of them sees
MIN_REGION_PX = 64      # fewer moving pixels than this: no figure (the region is too small to judge)
HOLE_ALPHA = 0.5        # a pixel is unobserved when its rendered alpha is below this
MIN_WEIGHT = 0.05       # a Gaussian is visible in an image when its summed blending weight >= this (pixels)

_GREY = np.array([0.299, 0.587, 0.114], np.float32)


def band_sharpness(image: np.ndarray, mask: np.ndarray) -> float | None:
    """Fine-over-medium detail of ``image`` [H,W,3] (float in [0,1] or uint8) on ``mask`` [H,W]:
    sum |I - blur(I, FINE_SIGMA)| / sum |I - blur(I, COARSE_SIGMA)| of the grey image over the
    mask's pixels; None when the mask has fewer than ``MIN_REGION_PX`` pixels or no detail."""
    mask = np.asarray(mask, bool)
    if mask.sum() < MIN_REGION_PX:
        return None
    a = np.asarray(image)
    a = a.astype(np.float32) / (255.0 if a.dtype == np.uint8 else 1.0)
    grey = a[..., :3] @ _GREY
    fine = np.abs(grey - cv2.GaussianBlur(grey, (0, 0), FINE_SIGMA))[mask].sum()
    coarse = np.abs(grey - cv2.GaussianBlur(grey, (0, 0), COARSE_SIGMA))[mask].sum()
    return float(fine / coarse) if coarse > 1e-4 * mask.sum() else None  # under 1e-4 per pixel: flat, no detail


def moving_and_holes(g: Gaussians, roi: np.ndarray, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(moving, unobserved) bool [H,W] of ``cam`` in one render: pixels the ``roi`` [N] Gaussians
    dominate (>= ``DYNAMIC_SHARE`` of an alpha >= ``DYNAMIC_ALPHA``), and pixels of alpha < ``HOLE_ALPHA``."""
    weights, alpha = render_effect_weights(g, np.asarray(roi, np.int64), {"roi": [1]}, cam)
    moving = (alpha >= DYNAMIC_ALPHA) & (weights["roi"] / np.maximum(alpha, 1e-6) >= DYNAMIC_SHARE)
    return moving, alpha < HOLE_ALPHA


@dataclass
class Photo:
    """A capture photo at the analysis scale: its camera, pixels (uint8 [H,W,3]), moving region
    (bool [H,W]) and the ROI Gaussians visible in it (bool [N])."""

    camera: Camera
    image: np.ndarray
    moving: np.ndarray
    seen: np.ndarray


class MotionSharpness:
    """The moving-region figures of candidate views against the capture photos (module docstring).

    ``g``: the canonical Gaussians (N); ``roi``: bool [N]; ``cameras`` and ``images``: the photos
    (the SfM cameras and the folder of the images they describe); ``max_side``: the photos are
    measured at most this size (the view's long side x 2 keeps them finer than any view).
    """

    def __init__(self, g: Gaussians, roi: np.ndarray, cameras: Sequence[Camera], images: str | Path,
                 max_side: int = 512):
        self.g, self.roi, self.max_side = g, np.asarray(roi, bool), int(max_side)
        self.photos: list[Photo] = []
        for cam in cameras:
            pix = load_image_compact(find_image(Path(images), cam.name))
            if pix.dtype != np.uint8:
                pix = (np.clip(pix, 0, 1) * 255 + 0.5).astype(np.uint8)
            h, w = pix.shape[:2]
            pix, cam = downscale(pix, cam if (w, h) == (cam.width, cam.height) else cam.scaled(w, h), max_side)
            moving, _ = moving_and_holes(g, self.roi, cam)
            if moving.sum() < MIN_REGION_PX:
                continue
            total, _ = blend_weights(g, cam)
            self.photos.append(Photo(cam, pix, moving, (total >= MIN_WEIGHT) & self.roi))
        log.info("views: %d of %d photos show the moving region (>= %d px at <= %d px): the references of the "
                 "motion-sharpness figure", len(self.photos), len(cameras), MIN_REGION_PX, max_side)

    def to_json(self) -> dict[str, Any]:
        """The figure's definition and constants, as recorded in ``views.json`` (``content.motion``)."""
        return {"fine_sigma_px": FINE_SIGMA, "coarse_sigma_px": COARSE_SIGMA, "reference_share": REFERENCE_SHARE,
                "similar_share": SIMILAR_SHARE, "min_region_px": MIN_REGION_PX, "hole_alpha": HOLE_ALPHA, "max_side": self.max_side,
                "reference_photos": [p.camera.name for p in self.photos],
                "definition": ("motion_sharpness: band sharpness (sum |I - blur(I, fine)| / sum |I - blur(I, coarse)| "
                               "of the grey image) of the view's render over its moving region (the ROI Gaussians "
                               "carry >= 0.5 of an alpha >= 0.3), over the same of the photo that samples them finest "
                               "among those that see >= reference_share of the view's visible moving Gaussians and >= "
                               "similar_share of what the best-seeing photo sees, that photo downsampled to the "
                               "view's sampling of them when it is finer (motion_scale k < 1); unobserved: share of "
                               "the view's pixels of rendered alpha < hole_alpha")}

    def reference(self, seen: np.ndarray, view: Camera) -> tuple[float, str, float] | None:
        """(band sharpness, photo name, sampling ratio k) of the photo that resolves the ``seen`` [N]
        moving Gaussians best: among the photos that see >= ``REFERENCE_SHARE`` of them and >=
        ``SIMILAR_SHARE`` of what the best-seeing photo sees (the same content), the one that samples
        them finest; measured at ``view``'s sampling (module docstring). None when no photo qualifies."""
        n = int(seen.sum())
        if n == 0:
            return None
        shared = [int((seen & p.seen).sum()) for p in self.photos]
        need = max(REFERENCE_SHARE * n, SIMILAR_SHARE * max(shared, default=0))
        view_fp = pixel_footprint(self.g, view)
        best: tuple[float, Photo] | None = None
        for p, m in zip(self.photos, shared):
            if m < need or m == 0:
                continue
            both = seen & p.seen
            k = float(np.median(pixel_footprint(self.g, p.camera)[both] / view_fp[both]))
            if best is None or k < best[0]:
                best = (k, p)
        if best is None:
            return None
        k, p = best
        image, moving = p.image, p.moving
        if k < 1.0:
            size = (max(8, round(p.camera.width * k)), max(8, round(p.camera.height * k)))
            image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
            moving = cv2.resize(moving.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
        s = band_sharpness(image, moving)
        return None if s is None else (s, p.camera.name, k)

    def measure(self, cam: Camera, rgb: np.ndarray) -> dict[str, Any]:
        """The figures of a view ``cam`` whose colour render is ``rgb`` [H,W,3]: ``motion_sharpness``
        (None: too small a moving region, or no photo sees it), ``motion_view`` and
        ``motion_photo`` (band sharpness), ``motion_reference`` (photo name), ``motion_scale`` (k),
        ``unobserved`` (share of pixels)."""
        moving, holes = moving_and_holes(self.g, self.roi, cam)
        out: dict[str, Any] = {"motion_sharpness": None, "motion_view": None, "motion_photo": None,
                               "motion_reference": None, "motion_scale": None, "unobserved": float(holes.mean())}
        sv = band_sharpness(rgb, moving)
        if sv is None:
            return out
        total, _ = blend_weights(self.g, cam)
        ref = self.reference((total >= MIN_WEIGHT) & self.roi, cam)
        out["motion_view"] = sv
        if ref is not None:
            out.update(motion_sharpness=sv / ref[0], motion_photo=ref[0], motion_reference=ref[1], motion_scale=ref[2])
        return out


def photo_pose_view(photo: Camera, width: int, height: int) -> Camera:
    """A view at a capture photo's pose with its field of view, ``width`` x ``height`` px
    (the photo's aspect is kept by cropping its intrinsics to the view's)."""
    fx = photo.K[0, 0] * width / photo.width
    fy = fx * photo.K[1, 1] / photo.K[0, 0]
    K = np.array([[fx, 0.0, width / 2.0], [0.0, fy, height / 2.0], [0.0, 0.0, 1.0]])
    return Camera(K=K, viewmat=photo.viewmat.copy(), width=width, height=height, name=photo.name)

