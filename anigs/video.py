"""Clip IO between stages (lossless npz), mp4 for people, and space-time slices.

A clip is float32 [T,H,W,3] in [0,1]. On disk: ``.npz`` with ``frames`` (float16 by
default: 11 mantissa bits, well below the 8-bit display step) plus optional metadata
(``camera`` JSON string, ``fps``, anything else as arrays). The members are stored, not
deflated: on rendered float16 frames deflate saves only about 25% of the bytes (the low
mantissa bits are noise to it) and costs 0.39 s per 256x192x25 clip against 0.008 s stored,
which was 40% of a round job's time on the demo (``benchmarks/clip_io.py``).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from anigs.io import atomic_path, write_npz


def _as_numpy(clip) -> np.ndarray:
    if hasattr(clip, "detach"):
        clip = clip.detach().cpu().numpy()
    return np.asarray(clip)


def check_clip(clip: np.ndarray, what: str = "clip") -> np.ndarray:
    """Validate a clip [T,H,W,3]; raise ValueError with the problem."""
    clip = _as_numpy(clip)
    if clip.ndim != 4 or clip.shape[-1] != 3:
        raise ValueError(f"{what}: expected [T,H,W,3], got {clip.shape}")
    if clip.shape[0] < 1:
        raise ValueError(f"{what}: has no frames")
    if not np.isfinite(clip).all():
        raise ValueError(f"{what}: contains NaN or Inf")
    return clip


def save_clip(path: str | Path, clip, meta: dict[str, Any] | None = None, dtype=np.float16) -> None:
    """Write a clip [T,H,W,3] in [0,1] to ``path`` (.npz, atomically)."""
    clip = check_clip(clip)
    arrays: dict[str, Any] = {"frames": np.clip(clip, 0, 1).astype(dtype)}
    arrays["meta"] = np.array(json.dumps(meta or {}))
    write_npz(path, compress=False, **arrays)


def load_clip(path: str | Path) -> tuple[np.ndarray, dict[str, Any]]:
    """Read a clip written by :func:`save_clip` -> (float32 [T,H,W,3], meta dict)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"clip not found: {path}")
    with np.load(path, allow_pickle=False) as z:
        frames = z["frames"].astype(np.float32)
        meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
    return check_clip(frames, str(path)), meta


def to_uint8(clip) -> np.ndarray:
    return (np.clip(_as_numpy(clip), 0, 1) * 255 + 0.5).astype(np.uint8)


def write_mp4(path: str | Path, clip, fps: int = 24, quality: int = 8) -> None:
    """Write an H.264 mp4 (sizes padded to even numbers, as yuv420p requires)."""
    import imageio.v2 as imageio

    frames = to_uint8(check_clip(clip))
    T, H, W, _ = frames.shape
    if H % 2 or W % 2:
        frames = np.pad(frames, ((0, 0), (0, H % 2), (0, W % 2), (0, 0)), mode="edge")
    with atomic_path(path) as tmp:
        with imageio.get_writer(tmp, fps=fps, codec="libx264", quality=quality, pixelformat="yuv420p",
                                macro_block_size=1, format="FFMPEG") as w:
            for f in frames:
                w.append_data(f)


def read_mp4(path: str | Path) -> np.ndarray:
    import imageio.v2 as imageio

    return np.stack([np.asarray(f) for f in imageio.mimread(str(path), memtest=False)]).astype(np.float32) / 255


def save_png(path: str | Path, image) -> None:
    """Write an image [H,W,3] or [H,W] in [0,1] (or uint8) as PNG, atomically."""
    import imageio.v2 as imageio

    img = _as_numpy(image)
    if img.dtype != np.uint8:
        img = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
    with atomic_path(path) as tmp:
        imageio.imwrite(tmp, img, format="PNG")
