"""``vegetation`` mask backend (default, offline): colour vegetation index + morphology.

Steps on an RGB frame [H,W,3] in [0,1]:

1. chromatic coordinates r,g,b = R,G,B / (R+G+B); index ExG-ExR = (2g-r-b) - (1.4r-g)
   (Meyer & Neto 2008; ``index: exg`` uses ExG alone);
2. exclusions: dark pixels (R+G+B < ``min_brightness``), grey pixels (HSV-style saturation
   (max-min)/max < ``min_saturation``: walls, roads, clouds) and sky (blue channel the
   largest, or bright and grey);
3. threshold: Otsu on the index of the remaining pixels, clipped to
   [``min_threshold``, ``max_threshold``] so a frame without vegetation (Otsu splits noise)
   or with only vegetation (Otsu splits leaves) stays sensible (``otsu: false``:
   ``min_threshold``; 0 is Meyer & Neto's plant rule, which keeps more dark foliage but also
   pixels that are mostly wall and a little leaf);
4. texture cue: ``texture_weight`` * local standard deviation of the luminance
   (``texture_window`` px) is added to the index before thresholding (foliage is textured);
5. optional flower cue: bright saturated (or, with a rendered alpha, white) pixels within
   ``flower_radius`` px of vegetation colour. With ``flowers_in_ground`` they count inside the
   ground layer of step 6 too: height cannot tell a flower bed from a fitted lawn that
   scatters by decimetres, colour can (a blossom is not green; lawn, soil and bricks are not
   bright and saturated). Single blossoms are a few pixels: ``flower_bed_radius`` closes them
   into beds, with the vegetation-coloured pixels between them (stems, leaves), before the
   small components of step 7 are dropped;
6. ground cue (when the frame carries a rendered depth and a camera and a ground plane is
   given): pixels whose surface lies within the ground layer are excluded: a green lawn is
   static ground, bushes and trees stand above it. The layer reaches
   :meth:`anigs.geometry.ground.GroundPlane.cut_height`: the fixed floor ``ground_margin`` * camera height, or, when
   the reconstructed ground is thicker (a fitted lawn floats and sinks by decimetres where it
   was poorly observed, and a ray sees the top of it), ``ground_layer`` * the thickness
   measured under the plane by :func:`anigs.geometry.ground.ground_plane`, capped at ``ground_max_margin`` *
   camera height; plus ``ground_depth_tol`` * the pixel's depth. Structures lower than the
   layer (grass tufts in a thick fitted lawn) are lost with it;
7. morphology: opening (``open_radius``), closing (``close_radius``), removal of connected
   components smaller than ``min_area`` (fraction of the frame) and of holes smaller than
   ``max_hole`` (fraction of the frame).

An all-sky or all-wall frame gives an empty mask. :func:`anigs.geometry.ground.ground_plane` finds
the ground plane of a Gaussian scene (densest low layer along ``up``), scales ``min_height`` by the
cameras' height above it, so the cue works in any reconstruction frame and scale, and
measures how thick the reconstructed ground layer is.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from anigs.typed_config import Section
from anigs.geometry.ground import GroundPlane, pixel_heights
from anigs.masks.frame import Frame
from anigs.pixels import check_image, fill_small_holes, remove_small, saturation


@dataclass
class VegetationConfig(Section):
    """Parameters of the vegetation-index masks (config section ``masks.vegetation``)."""

    WHERE = "masks.vegetation config"

    index: str = "exgr"          # exgr (ExG - ExR) | exg
    otsu: bool = True            # Otsu threshold (else min_threshold)
    min_threshold: float = 0.05  # lower clip of the index threshold
    max_threshold: float = 0.35  # upper clip of the index threshold
    min_saturation: float = 0.15 # below: grey (wall, road, cloud) -> excluded
    min_brightness: float = 0.06 # R+G+B below (of 3): too dark -> excluded
    min_alpha: float = 0.3       # with a rendered alpha: less = sky / empty (and no un-compositing)
    texture_weight: float = 0.0  # weight of the local luminance std added to the index
    texture_window: int = 5      # window (px) of the local std
    flowers: bool = True         # add saturated non-green blobs next to vegetation
    flower_saturation: float = 0.45  # minimum HSV saturation for a colourful (flower) pixel to count as vegetation
    flower_radius: int = 3       # px: how close to vegetation a flower pixel must be
    flower_min_value: float = 0.6  # brightest channel of a blossom (darker saturated = soil, bark)
    flowers_in_ground: bool = True  # blossoms count inside the ground layer too (next to green)
    flower_bed_radius: int = 3   # px: close the blossoms into beds (with the green between them), 0 = off
    open_radius: int = 0         # morphological opening radius (px), 0 = off (thin blades survive)
    close_radius: int = 0        # morphological closing radius (px), 0 = off
    min_area: float = 0.0005     # remove components smaller than this fraction of the frame
    max_hole: float = 0.002      # fill holes smaller than this fraction of the frame
    ground: bool = True          # use the ground cue when depth, camera and plane are available
    ground_margin: float = 0.03  # min height above ground, as a fraction of the camera height above it
    ground_depth_tol: float = 0.01  # plus this fraction of the pixel's depth (splat depth is coarse)
    ground_layer: float = 1.0    # times the ground layer's thickness measured by estimate_ground (0 = margin only)
    ground_max_margin: float = 0.3  # cap of the ground cut, as a fraction of the camera height

    def validate(self) -> None:
        if self.index not in ("exgr", "exg"):
            raise ValueError(f"vegetation.index must be 'exgr' or 'exg', got {self.index!r}")
        if self.ground_layer < 0 or self.ground_max_margin < 0:
            raise ValueError(f"vegetation: ground_layer ({self.ground_layer}) and ground_max_margin "
                             f"({self.ground_max_margin}) must be >= 0")
        if self.min_threshold > self.max_threshold:
            raise ValueError(f"vegetation: min_threshold {self.min_threshold} > max_threshold {self.max_threshold}")



def _disk(r: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def otsu_threshold(values: np.ndarray, bins: int = 256) -> float | None:
    """Otsu threshold of 1D ``values``; None when they are (nearly) constant."""
    v = np.asarray(values, np.float64).ravel()
    if v.size < 2:
        return None
    lo, hi = float(v.min()), float(v.max())
    if hi - lo < 1e-6:
        return None
    hist, edges = np.histogram(v, bins=bins, range=(lo, hi))
    centres = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(hist)
    w1 = w0[-1] - w0
    s0 = np.cumsum(hist * centres)
    m0 = s0 / np.maximum(w0, 1)
    m1 = (s0[-1] - s0) / np.maximum(w1, 1)
    between = w0 * w1 * (m0 - m1) ** 2
    k = int(np.argmax(between[:-1]))
    return float(edges[k + 1])


def vegetation_index(img: np.ndarray, index: str = "exgr") -> np.ndarray:
    """ExG-ExR (or ExG) [H,W] on chromatic coordinates of RGB [H,W,3] in [0,1]."""
    s = img.sum(-1, keepdims=True)
    c = img / np.maximum(s, 1e-6)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    exg = 2 * g - r - b
    return exg if index == "exg" else exg - (1.4 * r - g)


def vegetation_mask(image: np.ndarray, cfg: VegetationConfig | None = None, name: str = "",
                    frame: Frame | None = None, ground: GroundPlane | None = None) -> np.ndarray:
    """Vegetation mask bool [H,W] of an RGB frame (see module docstring).

    ``frame`` (with ``depth`` and ``camera``) and ``ground`` enable the ground cue.
    """
    cfg = cfg or VegetationConfig()
    img = check_image(image, name)
    h, w = img.shape[:2]
    has_alpha = frame is not None and frame.alpha is not None
    if has_alpha and frame.background is not None:
        # un-composite semi-transparent pixels (leaf edges over the sky): C = F a + (1 - a) bg
        a = np.asarray(frame.alpha, np.float32)[..., None]
        fg = (img - (1 - a) * np.asarray(frame.background, np.float32)) / np.maximum(a, 1e-3)
        img = np.where(a >= cfg.min_alpha, np.clip(fg, 0, 1), img).astype(np.float32)
    bright = img.sum(-1)
    sat = saturation(img)
    idx = vegetation_index(img, cfg.index)
    if cfg.texture_weight > 0:
        lum = img @ np.array([0.299, 0.587, 0.114], np.float32)
        k = (cfg.texture_window, cfg.texture_window)
        mean = cv2.blur(lum, k)
        std = np.sqrt(np.maximum(cv2.blur(lum * lum, k) - mean * mean, 0))
        idx = idx + cfg.texture_weight * std
    grey = sat < cfg.min_saturation
    sky_colour = (img[..., 2] >= img[..., 1]) & (img[..., 2] >= img[..., 0])
    # with a rendered alpha, "sky" is where there is no geometry; otherwise a colour rule
    sky = (np.asarray(frame.alpha) < cfg.min_alpha) if has_alpha else sky_colour
    valid = (bright >= cfg.min_brightness) & ~grey & ~sky
    if frame is None or frame.alpha is None:
        valid &= ~sky_colour
    valid_colour = valid.copy()
    above = np.ones((h, w), bool)  # surfaces standing above the ground layer (all, without the ground cue)
    if cfg.ground and ground is not None and frame is not None and frame.depth is not None and frame.camera is not None:
        depth = np.asarray(frame.depth, np.float64)
        if depth.shape != (h, w):
            raise ValueError(f"frame {name!r}: depth is {depth.shape[1]}x{depth.shape[0]} but the image is {w}x{h}")
        seen = depth > 0 if frame.alpha is None else (np.asarray(frame.alpha) >= 0.5) & (depth > 0)
        height = pixel_heights(depth, frame.camera, ground) - cfg.ground_depth_tol * depth
        above = ~(seen & (height < ground.cut_height(cfg.ground_layer, cfg.ground_max_margin)))
        valid &= above
    thr = cfg.min_threshold
    if cfg.otsu and valid.sum() >= 16:
        t = otsu_threshold(idx[valid])
        if t is not None:
            thr = float(np.clip(t, cfg.min_threshold, cfg.max_threshold))
    mask = valid & (idx > thr)
    green = valid_colour & (idx > thr)  # vegetation colour, ground layer included
    if cfg.flowers and (mask.any() or (cfg.flowers_in_ground and green.any())):
        # colourful (or white) blossoms next to vegetation: any hue, blue included once the
        # geometry tells sky apart
        seeds = (mask | green) if cfg.flowers_in_ground else mask
        near = cv2.dilate(seeds.astype(np.uint8), _disk(max(cfg.flower_radius, 1))) > 0
        white = (img.min(-1) >= 0.75) & (sat < cfg.min_saturation)
        colourful = (sat >= cfg.flower_saturation) & (img.max(-1) >= cfg.flower_min_value)  # not soil
        if frame is None or frame.alpha is None:
            colourful &= ~sky_colour
            white[:] = False
        flower = (colourful | white) & ~sky & (idx <= thr) & near
        if not cfg.flowers_in_ground:
            flower &= above
        if cfg.flower_bed_radius > 0 and flower.any():
            # single blossoms are a few pixels: close them into beds, with the green stems and
            # leaves between them (inside the ground layer too), before small components go
            bed = cv2.morphologyEx(flower.astype(np.uint8), cv2.MORPH_CLOSE, _disk(cfg.flower_bed_radius)) > 0
            flower |= bed & (green | colourful | white) & ~sky
        mask |= flower
    if cfg.open_radius > 0:
        mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, _disk(cfg.open_radius)) > 0
    if cfg.close_radius > 0:
        mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, _disk(cfg.close_radius)) > 0
    mask = remove_small(mask, int(round(cfg.min_area * h * w)))
    mask = fill_small_holes(mask, int(round(cfg.max_hole * h * w)))
    return mask


class VegetationBackend:
    """Callable mask backend: ``{"dynamic": vegetation_mask(frame.image)}``."""

    def __init__(self, cfg: VegetationConfig, ground: GroundPlane | None = None):
        self.cfg, self.ground = cfg, ground

    def __call__(self, frame: Frame) -> dict[str, np.ndarray]:
        return {"dynamic": vegetation_mask(frame.image, self.cfg, frame.name, frame, self.ground)}


def build(config: dict | VegetationConfig | None = None, ground: GroundPlane | None = None,
          **kwargs) -> VegetationBackend:
    """Registry entry: a config dict / dataclass (or its fields as keywords), optional ground plane."""
    if isinstance(config, VegetationConfig):
        cfg = config
    else:
        cfg = VegetationConfig.from_dict({**(config or {}), **kwargs})
    return VegetationBackend(cfg, ground)
