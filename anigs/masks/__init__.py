"""Dynamic-region masks per view: registry of backends and the common checks.

A backend is a callable ``backend(frame: Frame) -> dict[str, bool [H,W]]`` returning the
key ``"dynamic"`` (union of all effects) and optionally one key per effect type. Backends:

=============  ==============================================================================
``vegetation`` default, offline: colour vegetation index + Otsu + texture + morphology
``labels``     synthetic scenes: label map rendered from labelled Gaussians (the yardstick)
``sam2``       optional: SAM2 automatic masks filtered by vegetation score, or point prompts
=============  ==============================================================================

Use :func:`get_mask_backend` to build one by name and :func:`compute_masks` to run it on
frames with the input and output checks (NaN pixels and wrong-size masks are errors). Mask
files are read and written by :mod:`anigs.images`, frames checked by :mod:`anigs.pixels`.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from anigs.masks import labels_backend, sam2, vegetation
from anigs.masks.frame import Frame, MaskBackend, render_frames
from anigs.pixels import check_image

# name -> the backend's builder (sam2 imports the sam2 package only when its backend is built)
MASK_BACKENDS: dict[str, Callable[..., MaskBackend]] = {
    "vegetation": vegetation.build,
    "labels": labels_backend.build,
    "sam2": sam2.build,
}


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
    return MASK_BACKENDS[name](**kwargs)


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


__all__ = ["Frame", "MaskBackend", "MASK_BACKENDS", "get_mask_backend", "compute_masks", "check_mask_size",
           "mask_iou", "render_frames"]
