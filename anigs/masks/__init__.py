"""Dynamic-region masks per view: registry of backends and the common checks.

A backend is a callable ``backend(frame: Frame) -> dict[str, bool [H,W]]`` returning the
key ``"dynamic"`` (union of all effects) and optionally one key per effect type. Backends:

=============  ==============================================================================
``vegetation`` default, offline: colour vegetation index + Otsu + texture + morphology
``labels``     synthetic scenes: label map rendered from labelled Gaussians (the yardstick)
``sam2``       optional: SAM2 automatic masks filtered by vegetation score, or point prompts
=============  ==============================================================================

Use :func:`get_mask_backend` to build one by name and :func:`compute_masks` to run it on
frames with the input and output checks (NaN pixels and wrong-size masks are errors).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import cv2
import numpy as np

from anigs.cameras import Camera
from anigs.io import atomic_path

MASK_BACKENDS: dict[str, str] = {
    "vegetation": "anigs.masks.vegetation",
    "labels": "anigs.masks.labels",
    "sam2": "anigs.masks.sam2",
}


@dataclass
class Frame:
    """One image to segment.

    Attributes:
        image: RGB [H,W,3] float in [0,1] (uint8 accepted, converted).
        camera: the camera it was rendered/taken with (needed by ``labels``; optional otherwise).
        depth: rendered expected depth [H,W] (optional; enables the ground cue of ``vegetation``).
        alpha: rendered alpha [H,W] (optional).
        name: identifier used in messages and file names.
        background: RGB [3] the frame was rendered over (optional; with ``alpha`` it lets the
            vegetation backend recover the foreground colour of semi-transparent pixels).
    """

    image: np.ndarray
    camera: Camera | None = None
    depth: np.ndarray | None = None
    alpha: np.ndarray | None = None
    name: str = ""
    background: np.ndarray | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(height, width)."""
        return int(self.image.shape[0]), int(self.image.shape[1])


MaskBackend = Callable[[Frame], dict[str, np.ndarray]]


def check_image(image: np.ndarray, name: str = "") -> np.ndarray:
    """Validate an RGB frame; return float32 [H,W,3] in [0,1]. NaN/Inf pixels are an error."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"frame {name!r}: expected an RGB image [H,W,3], got shape {img.shape}")
    if img.dtype == np.uint8:
        img = img.astype(np.float32) / 255.0
    img = img[..., :3].astype(np.float32)
    bad = ~np.isfinite(img)
    if bad.any():
        ys, xs = np.nonzero(bad.any(-1))
        raise ValueError(f"frame {name!r}: {len(ys)} pixels are NaN/Inf (first at x={xs[0]}, y={ys[0]}); "
                         "the rendered frame is broken, refusing to compute a mask")
    return np.clip(img, 0.0, 1.0)


def check_mask_size(mask: np.ndarray, size: tuple[int, int], name: str = "", key: str = "dynamic") -> np.ndarray:
    """Return ``mask`` as bool [H,W]; a size different from ``size`` (H,W) is an error naming both."""
    m = np.asarray(mask)
    if m.ndim != 2 or m.shape != tuple(size):
        got = f"{m.shape[1]}x{m.shape[0]}" if m.ndim == 2 else f"shape {m.shape}"
        raise ValueError(f"mask {key!r} of frame {name!r} is {got} (WxH) but the frame is {size[1]}x{size[0]}")
    return m.astype(bool)


def get_mask_backend(name: str, **kwargs: Any) -> MaskBackend:
    """Build the mask backend ``name`` (``vegetation``, ``labels``, ``sam2``) with its keyword options."""
    if name not in MASK_BACKENDS:
        raise ValueError(f"unknown mask backend {name!r}; choose one of {sorted(MASK_BACKENDS)}")
    module = importlib.import_module(MASK_BACKENDS[name])
    return module.build(**kwargs)


def compute_masks(backend: MaskBackend | str, frames: Sequence[Frame], **kwargs: Any) -> list[dict[str, np.ndarray]]:
    """Run ``backend`` (a backend or its name, then built with ``kwargs``) on ``frames``.

    Returns one dict per frame with bool [H,W] masks; ``"dynamic"`` is always present and
    contains every effect mask.
    """
    if isinstance(backend, str):
        backend = get_mask_backend(backend, **kwargs)
    out = []
    for fr in frames:
        img = check_image(fr.image, fr.name)
        fr = Frame(img, fr.camera, fr.depth, fr.alpha, fr.name, fr.background)
        if fr.camera is not None and (fr.camera.height, fr.camera.width) != fr.size:
            raise ValueError(f"frame {fr.name!r} is {fr.size[1]}x{fr.size[0]} (WxH) but its camera is "
                             f"{fr.camera.width}x{fr.camera.height}")
        res = backend(fr)
        if "dynamic" not in res:
            raise RuntimeError(f"mask backend returned no 'dynamic' mask for frame {fr.name!r}")
        res = {k: check_mask_size(v, fr.size, fr.name, k) for k, v in res.items()}
        for v in res.values():
            res["dynamic"] = res["dynamic"] | v
        out.append(res)
    return out


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two bool masks; 1.0 when both are empty."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    if a.shape != b.shape:
        raise ValueError(f"IoU: masks differ in size: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    union = int((a | b).sum())
    return 1.0 if union == 0 else float((a & b).sum() / union)


def overlay(image: np.ndarray, mask: np.ndarray, colour=(1.0, 0.15, 0.6), strength: float = 0.5) -> np.ndarray:
    """RGB float [H,W,3]: the image with the mask tinted and its outline drawn."""
    img = check_image(image)
    m = np.asarray(mask, bool)
    out = img.copy()
    out[m] = (1 - strength) * out[m] + strength * np.asarray(colour, np.float32)
    edge = m.astype(np.uint8) - cv2.erode(m.astype(np.uint8), np.ones((3, 3), np.uint8))
    out[edge > 0] = colour
    return out


def write_mask_png(path: str | Path, mask: np.ndarray) -> None:
    """Write a bool mask as an 8-bit PNG (0 / 255), atomically."""
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), np.asarray(mask, bool).astype(np.uint8) * 255):
            raise RuntimeError(f"could not write mask {path}")


def read_mask(path: str | Path) -> np.ndarray:
    """The one mask reader: a PNG (8 or 16 bit, 0..255 / 0..65535 or 0/1; colour channels: their
    maximum; alpha ignored) or an ``.npy`` array -> soft mask float32 [H,W] in [0,1]
    (0/255 PNGs give exactly 0 and 1)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"mask file not found: {path}")
    if path.suffix == ".npy":
        m = np.asarray(np.load(path), np.float32)
        if m.ndim == 3:
            m = m[..., :3].max(-1)
        return m / 255.0 if m.max(initial=0) > 1.0 else m
    m = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if m is None:
        raise ValueError(f"could not read mask image {path}")
    if m.ndim == 3:
        m = m[..., :3].max(-1)
    scale = 65535.0 if m.dtype == np.uint16 else 255.0
    m = m.astype(np.float32)
    return m / scale if m.max(initial=0) > 1.0 else m  # 0/1 PNGs are masks too


def read_mask_png(path: str | Path) -> np.ndarray:
    """Read a mask (see :func:`read_mask`) as bool [H,W]: any non-zero pixel is True."""
    return read_mask(path) > 0


def write_rgb_png(path: str | Path, image: np.ndarray) -> None:
    """Write RGB float [H,W,3] in [0,1] as PNG, atomically."""
    img = (np.clip(np.asarray(image, np.float32), 0, 1) * 255 + 0.5).astype(np.uint8)
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img[..., ::-1]):
            raise RuntimeError(f"could not write image {path}")


def read_rgb_png(path: str | Path) -> np.ndarray:
    """Read an image file as RGB float32 [H,W,3] in [0,1] (:func:`anigs.images.load_image`)."""
    from anigs.images import load_image

    return load_image(path)


def render_frames(gaussians, cameras: Sequence[Camera], background: Sequence[float] | None = None) -> list[Frame]:
    """Render ``gaussians`` from each camera: Frames with image, depth and alpha (frustum-culled first)."""
    import torch

    from anigs.masks.lift import frustum_subset
    from anigs.render import render_gaussians

    bg = None if background is None else torch.tensor(list(background), dtype=torch.float32)
    frames = []
    for cam in cameras:
        sub = gaussians.subset(frustum_subset(gaussians, cam))
        with torch.no_grad():
            rgb, alpha, meta = render_gaussians(sub, cam, background=bg)
        frames.append(Frame(rgb.clamp(0, 1).numpy(), cam, meta["depth"].numpy(), alpha.numpy(), cam.name,
                            None if background is None else np.asarray(background, np.float32)))
    return frames


__all__ = ["Frame", "MaskBackend", "MASK_BACKENDS", "get_mask_backend", "compute_masks", "check_image",
           "check_mask_size", "mask_iou", "overlay", "write_mask_png", "read_mask_png", "write_rgb_png",
           "render_frames", "read_rgb_png"]
