"""2D cues of effect detection on one photo: colour classes, texture and connected components.

All functions take RGB float [H,W,3] in [0,1] or bool / float maps [H,W] and return [H,W] maps
(or per-component arrays indexed by the component label, 0 = background).
"""
from __future__ import annotations

import cv2
import numpy as np

from anigs.pixels import fill_small_holes, remove_small, saturation

LUMA_WEIGHTS = (0.299, 0.587, 0.114)  # the luminance of an RGB colour: these weights of R, G and B (Rec. 601)
LUMA = np.array(LUMA_WEIGHTS, np.float32)
WHITE_MIN_VALUE = 0.8  # a white blossom: every channel at least this bright (fraction of full intensity) ...
WHITE_MAX_SATURATION = 0.15  # ... and less saturated than this ((max - min) / max)
MIN_WINDOW = 3  # the texture's box is at least this wide (px)
CONNECTIVITY = 8  # components are 8-connected: pixels touching at a corner join (cv2's connectivity)
MIN_RECT_PIXELS = 16  # no rectangularity is measured for a component under this many pixels (px)


def disk(r: int) -> np.ndarray:
    """Elliptic structuring element of radius ``r`` (px)."""
    r = max(int(r), 1)
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def hsv(img: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hue [H,W] in degrees [0,360), saturation (max-min)/max and value max, each [H,W]."""
    h = cv2.cvtColor(np.ascontiguousarray(img, np.float32), cv2.COLOR_RGB2HSV)[..., 0]
    return h, saturation(img), img.max(-1)


def in_band(hue: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    """Hue inside [low, high] degrees."""
    return (hue >= band[0]) & (hue <= band[1])


def green(img: np.ndarray, hue_band: tuple[float, float], min_sat: float, min_value: float,
          min_chroma: float = 0.0) -> np.ndarray:
    """Vegetation colour: a green hue at any brightness above ``min_value`` (dark, shaded foliage
    included), saturated enough to be a colour, with a chroma (max - min channel) of at least
    ``min_chroma`` (below it the hue of a dark pixel is noise), and green not below red (``G >= R``)."""
    h, s, v = hsv(img)
    chroma = img.max(-1) - img.min(-1)
    return in_band(h, hue_band) & (s >= min_sat) & (v >= min_value) & (chroma >= min_chroma) & \
        (img[..., 1] >= img[..., 0])


def colourful(img: np.ndarray, green_band: tuple[float, float], min_sat: float, min_value: float,
              white: bool) -> np.ndarray:
    """Blossom colour: saturated and bright with a hue outside the green band (any other hue: red,
    yellow, blue, violet ...), or, with ``white``, bright near-white."""
    h, s, v = hsv(img)
    out = (s >= min_sat) & (v >= min_value) & ~in_band(h, green_band)
    if white:
        out |= (img.min(-1) >= WHITE_MIN_VALUE) & (s < WHITE_MAX_SATURATION)
    return out


def texture(img: np.ndarray, window: int) -> np.ndarray:
    """Local standard deviation [H,W] of the luminance in a ``window`` x ``window`` box."""
    lum = img @ LUMA
    k = (max(int(window), MIN_WINDOW),) * 2
    mean = cv2.blur(lum, k)
    return np.sqrt(np.maximum(cv2.blur(lum * lum, k) - mean * mean, 0.0))


def clean(mask: np.ndarray, min_pixels: int, hole_pixels: int) -> np.ndarray:
    """Drop components smaller than ``min_pixels`` and fill holes up to ``hole_pixels``."""
    return fill_small_holes(remove_small(np.asarray(mask, bool), min_pixels), hole_pixels)


def mask_components(mask: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """8-connected components: (count incl. background, labels [H,W] int32, areas [count])."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats(np.asarray(mask, np.uint8), connectivity=CONNECTIVITY)
    return n, lab, stats[:, cv2.CC_STAT_AREA].astype(np.int64)


def ring_share(labels: np.ndarray, n: int, radius: int, inside: np.ndarray) -> np.ndarray:
    """Per component [n]: the share of its surrounding ring (``radius`` px wide, outside every
    component) where ``inside`` holds (0 where the ring is empty)."""
    grown = cv2.dilate(labels.astype(np.float32), disk(radius)).astype(np.int64)
    ring = (labels == 0) & (grown > 0)
    total = np.bincount(grown[ring], minlength=n)[:n]
    hit = np.bincount(grown[ring & inside], minlength=n)[:n]
    return np.where(total > 0, hit / np.maximum(total, 1), 0.0)


def ring_depth_gap(labels: np.ndarray, n: int, radius: int, depth: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Per component [n]: (median depth of the component - median depth of its ring pixels where
    ``inside`` holds) / median depth of the component (nan where either is empty): > 0 when the
    component lies behind the surface around it, < 0 in front of it."""
    grown = cv2.dilate(labels.astype(np.float32), disk(radius)).astype(np.int64)
    ring = (labels == 0) & (grown > 0) & inside & (depth > 0)
    own = cue_median(labels, n, depth, (labels > 0) & (depth > 0))
    around = cue_median(grown, n, depth, ring)
    return (own - around) / np.maximum(own, 1e-9)


def cue_median(labels: np.ndarray, n: int, values: np.ndarray, where: np.ndarray) -> np.ndarray:
    """Per label [n]: the median of ``values`` over the pixels where ``where`` holds (nan if none)."""
    lab, v = labels[where], values[where]
    out = np.full(n, np.nan)
    if not len(lab):
        return out
    order = np.lexsort((v, lab))
    lab, v = lab[order], v[order]
    bounds = np.searchsorted(lab, np.arange(n + 1))
    for i in np.flatnonzero(bounds[1:] > bounds[:-1]):
        seg = v[bounds[i]:bounds[i + 1]]
        out[i] = float(seg[len(seg) // 2])
    return out


def rectangularity(labels: np.ndarray, n: int, areas: np.ndarray, min_pixels: int) -> np.ndarray:
    """Per component [n]: area / area of its minimum-area rotated rectangle (1 = a rectangle; an
    ellipse is ~0.79, ragged foliage lower); 0 for components under ``min_pixels``."""
    out = np.zeros(n)
    for i in np.flatnonzero(areas >= max(min_pixels, MIN_RECT_PIXELS)):
        if i == 0:
            continue
        ys, xs = np.nonzero(labels == i)
        (_, _), (w, h), _ = cv2.minAreaRect(np.column_stack([xs, ys]).astype(np.float32))
        out[i] = areas[i] / max((w + 1) * (h + 1), 1.0)
    return out


def component_quantile(labels: np.ndarray, n: int, values: np.ndarray, q: float) -> np.ndarray:
    """Per component [n]: the ``q`` quantile of ``values`` [H,W] over its pixels (nan if empty)."""
    out = np.full(n, np.nan)
    flat, v = labels.ravel(), values.ravel()
    order = np.argsort(flat, kind="stable")
    bounds = np.searchsorted(flat[order], np.arange(n + 1))
    for i in range(1, n):
        seg = v[order[bounds[i]:bounds[i + 1]]]
        seg = seg[np.isfinite(seg)]
        if len(seg):
            out[i] = float(np.quantile(seg, q))
    return out
