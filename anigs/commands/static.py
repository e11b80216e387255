"""``anigs static``: fit the static canonical 3DGS from posed images and SfM points.

    anigs static --images DIR --cameras sfm/cameras.json --points sfm/points.npz \
                 --out results/demo/static [--params JSON]

Writes ``OUT/canonical.ply`` (standard 3DGS layout) and ``OUT/metrics.json``. While it runs,
``OUT/checkpoint.ply`` holds the last good state; it is removed on success and kept when the
fit diverges.
"""
from __future__ import annotations

import os

# Under CPU oversubscription, OpenMP's default spin-waiting makes every parallel kernel
# ~10x slower; passive waiting costs little when the cores are free. Must precede torch.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse  # noqa: E402
import logging  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

log = logging.getLogger("anigs.static")

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".PNG", ".JPG", ".JPEG")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--images", required=True, help="folder of the input images")
    p.add_argument("--cameras", required=True, help="cameras.json (anigs convention), one entry per used image")
    p.add_argument("--points", required=True, help="points.npz with xyz [P,3] and rgb [P,3] (SfM points)")
    p.add_argument("--out", required=True, help="output folder (canonical.ply, metrics.json)")
    p.add_argument("--params", default=None, help="static config section as JSON or @file.json")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def load_points(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """SfM points [P,3] and colours [P,3] in [0,1] from an npz (keys xyz/rgb or points/colors)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"SfM points file not found: {path} (written by `anigs sfm`)")
    with np.load(path) as data:
        keys = set(data.files)
        pk = next((k for k in ("xyz", "points") if k in keys), None)
        ck = next((k for k in ("rgb", "colors") if k in keys), None)
        if pk is None:
            raise KeyError(f"{path}: no point array (expected key 'xyz' or 'points'; found {sorted(keys)})")
        pts = np.asarray(data[pk], dtype=np.float64)
        if ck is None:
            log.warning("%s has no colours ('rgb'/'colors'): initialising grey", path)
            cols = np.full_like(pts, 0.5)
        else:
            cols = np.asarray(data[ck])
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{path}: '{pk}' must be [P,3], got {pts.shape}")
    if cols.shape != pts.shape:
        raise ValueError(f"{path}: colours {cols.shape} do not match points {pts.shape}")
    cols = cols.astype(np.float64) / 255.0 if np.issubdtype(cols.dtype, np.integer) or cols.max(initial=0) > 1.5 \
        else cols.astype(np.float64)
    return pts, np.clip(cols, 0, 1)


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


def load_image(path: Path) -> np.ndarray:
    """float32 [H,W,3] in [0,1]."""
    from PIL import Image, ImageOps

    try:
        with Image.open(path) as im:
            im = ImageOps.exif_transpose(im).convert("RGB")
            return np.asarray(im, dtype=np.float32) / 255.0
    except OSError as exc:
        raise ValueError(f"cannot read image {path}: {exc}") from exc


def load_inputs(images: str | Path, cameras: str | Path):
    """Images (torch [H,W,3]) and cameras in camera-file order; cameras are rescaled to the image size."""
    import torch

    from anigs.cameras import load_cameras

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
        arr = load_image(p)
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


def run(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.fit import FitConfig, fit_static
    from anigs.gaussians import load_ply
    from anigs.io import write_json

    cfg = FitConfig.from_dict(parse_params(args.params))
    out = Path(args.out)
    imgs, cams = load_inputs(args.images, args.cameras)
    pts, cols = load_points(args.points)
    out.mkdir(parents=True, exist_ok=True)
    ckpt = out / "checkpoint.ply"
    gaussians, metrics = fit_static(imgs, cams, pts, cols, cfg, progress=not args.no_progress, checkpoint_path=ckpt)
    ply = out / "canonical.ply"
    gaussians.save_ply(ply)
    back = load_ply(ply)  # the artifact must round-trip
    if back.num != gaussians.num:
        raise RuntimeError(f"{ply}: wrote {gaussians.num} Gaussians but read back {back.num}")
    metrics["inputs"] = {"images": str(args.images), "cameras": str(args.cameras), "points": str(args.points),
                         "num_points": int(len(pts))}
    metrics["config"] = _config_dict(cfg)
    write_json(out / "metrics.json", metrics)
    if ckpt.exists():
        ckpt.unlink()
    print(f"static fit: {metrics['num_gaussians']} Gaussians, held-out PSNR {metrics['test_psnr']:.2f} dB "
          f"(SSIM {metrics['test_ssim']:.3f}), train PSNR {metrics['train_psnr']:.2f} dB, "
          f"{metrics['seconds']:.0f} s -> {ply}")
    return 0


def _config_dict(cfg) -> dict:
    import dataclasses

    d = dataclasses.asdict(cfg)
    d["background"] = list(cfg.background)
    return d
