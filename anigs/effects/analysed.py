"""The photos effect detection analyses: evenly spaced, downscaled, with their cameras."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from anigs.cameras import Camera, camera_for_size
from anigs.effects.config import PhotosConfig
from anigs.images import downscale
from anigs.pixels import check_image


def photo_indices(num_photos: int, max_photos: int) -> np.ndarray:
    """The evenly spaced photos the detection analyses (indices into the capture's cameras): a caller
    need read only these (``effects.photos.max_photos``, 24: not all of a 384-photo capture in memory at once)."""
    return np.unique(np.round(np.linspace(0, num_photos - 1, min(num_photos, max_photos))).astype(int))


def prepare_photos(images: Sequence[np.ndarray], cameras: Sequence[Camera], cfg: PhotosConfig) -> tuple[list, list]:
    """Evenly spaced photos (float32 [H,W,3]) downscaled to ``max_side``, with their cameras."""
    if len(images) != len(cameras):
        raise ValueError(f"detect_effects: {len(images)} images but {len(cameras)} cameras")
    if not len(images):
        raise ValueError("detect_effects: no photos")
    pick = photo_indices(len(images), cfg.max_photos)
    photos, cams = [], []
    for i in pick:
        img = check_image(images[i], cameras[i].name)
        h, w = img.shape[:2]
        cam = camera_for_size(cameras[i], h, w, f"photo {cameras[i].name!r}")
        img, cam = downscale(img, cam, cfg.max_side)
        photos.append(np.ascontiguousarray(img, np.float32))
        cams.append(cam)
    return photos, cams
