"""Image and mask files.

``find_image`` maps a camera name to its file; ``load_image`` (the one image reader) reads
RGB float32 [H,W,3] in [0,1]; ``load_inputs`` pairs a cameras JSON with its image folder, rescaling intrinsics to
the image size. ``write_rgb_png`` writes an RGB image; ``read_mask`` (the one mask reader),
``read_mask_png`` and ``write_mask_png`` read and write masks. Writes are atomic. ``downscale`` brings an
image and its camera to at most a given longest side (the static fit, the views' references, the effects' photos).
"""
from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from anigs.cameras import Camera, load_cameras
from anigs.io import atomic_path

log = logging.getLogger("anigs.images")

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG")


def find_image(image_dir: Path, name: str) -> Path:
    """The image file for camera ``name`` (exact file name, or stem + a known suffix)."""
    cand = image_dir / name
    if cand.is_file():
        return cand
    stem = Path(name).stem
    for suf in IMAGE_SUFFIXES:
        if (image_dir / (stem + suf)).is_file():
            return image_dir / (stem + suf)
    raise FileNotFoundError(f"no image for camera {name!r} in {image_dir}")


def _read_rgb(path: str | Path) -> np.ndarray:
    """The file's pixels as stored: uint8 or uint16 [H,W,3] RGB (grey repeated, alpha dropped)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"image not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"cannot read image {path}")
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, 2)
    return img[..., :3][..., ::-1]


def load_image(path: str | Path) -> np.ndarray:
    """The one image reader: RGB float32 [H,W,3] in [0,1] from an 8- or 16-bit image file (grey is
    repeated to RGB, alpha dropped). EXIF orientation is applied once, when photos are imported
    (:mod:`anigs.photos`): every image a stage reads afterwards is an upright PNG."""
    return _to_float(_read_rgb(path))


def _to_float(img: np.ndarray) -> np.ndarray:
    """float32 [H,W,3] in [0,1] of stored pixels (16-bit / 65535, else / 255)."""
    scale = 65535.0 if img.dtype == np.uint16 else 255.0
    return (img.astype(np.float32) / scale).copy()


def load_image_compact(path: str | Path) -> np.ndarray:
    """:func:`load_image`'s pixels at a quarter of the memory: uint8 [H,W,3] for an 8-bit file (the
    float image is exactly ``img.astype(float32) / 255``, what :func:`load_image` gives), float32 [H,W,3]
    in [0,1] otherwise. A 384-photo capture at 1280x960 holds 1.4 GB instead of 5.7 GB."""
    img = _read_rgb(path)
    return img.copy() if img.dtype == np.uint8 else _to_float(img)


def load_inputs(images: str | Path, cameras: str | Path, compact: bool = False):
    """Images (torch [H,W,3]) and cameras in camera-file order; cameras are rescaled to the image size.
    ``compact``: 8-bit images stay uint8 (:func:`load_image_compact`; a quarter of the memory)."""
    import torch

    image_dir = Path(images)
    if not image_dir.is_dir():
        raise FileNotFoundError(f"image folder not found: {image_dir}")
    cams = load_cameras(cameras)
    if not cams:
        raise ValueError(f"{cameras}: no cameras")
    missing, imgs, out_cams = [], [], []
    for cam in cams:
        try:
            p = find_image(image_dir, cam.name)
        except FileNotFoundError:
            missing.append(cam.name)
            continue
        arr = load_image_compact(p) if compact else load_image(p)
        h, w = arr.shape[:2]
        if (w, h) != (cam.width, cam.height):
            log.info("camera %s is %dx%d, image %dx%d: scaling intrinsics", cam.name, cam.width, cam.height, w, h)
            cam = cam.scaled(w, h)
        imgs.append(torch.from_numpy(arr))
        out_cams.append(cam)
    if missing:
        raise FileNotFoundError(f"{len(missing)} of {len(cams)} cameras in {cameras} have no image in {image_dir}: "
                                f"{missing[:10]}{' ...' if len(missing) > 10 else ''}")
    return imgs, out_cams


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


def fit_scale(width: int, height: int, max_side: int) -> float:
    """Downscale factor (<= 1) that brings the longest side to at most ``max_side`` (0: 1)."""
    return 1.0 if max_side <= 0 or max(width, height) <= max_side else max_side / max(width, height)


def downscale(image: np.ndarray, cam: Camera, max_side: int) -> tuple[np.ndarray, Camera]:
    """``image`` [H,W,3] (uint8 or float) and ``cam`` at most ``max_side`` px on the longest side (area
    interpolation; 0 or already smaller: the same objects back)."""
    f = fit_scale(cam.width, cam.height, max_side)
    if f >= 1.0:
        return image, cam
    w, h = max(1, round(cam.width * f)), max(1, round(cam.height * f))
    return cv2.resize(np.ascontiguousarray(image), (w, h), interpolation=cv2.INTER_AREA), cam.scaled(w, h)
