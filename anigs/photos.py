"""User photos: find them, check they decode and can form a capture, import them as upright PNGs.

``import_photos`` is the "folder of photos" input form: JPEG/PNG files are decoded,
rotated according to their EXIF orientation (COLMAP ignores that tag), optionally
downscaled so the longest side is at most ``max_side``, and written as PNGs.
"""
from __future__ import annotations

import logging
from pathlib import Path

from anigs.io import atomic_path

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
MIN_IMAGES = 3


def list_images(folder: str | Path) -> list[Path]:
    """Image files (JPEG/PNG, any case) directly in ``folder``, sorted by name.

    Raises FileNotFoundError when the folder is missing or holds no image file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"image folder not found: {folder}")
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise FileNotFoundError(f"no JPEG/PNG images in {folder}")
    return files


def _decode(path: Path):
    """Fully decode one image with PIL (``verify`` alone misses truncated data)."""
    from PIL import Image

    with Image.open(path) as im:
        im.load()
        return im.copy()


def check_images(paths: list[Path]) -> tuple[list[Path], list[str]]:
    """Split ``paths`` into readable images and ``"name: reason"`` strings for the others."""
    good, bad = [], []
    for p in paths:
        try:
            im = _decode(p)
            if im.width < 1 or im.height < 1:
                raise ValueError("empty image")
            good.append(p)
        except Exception as exc:  # PIL raises many types for corrupt data
            bad.append(f"{p.name}: {type(exc).__name__}: {exc}")
    return good, bad


def image_headers(paths: list[Path]) -> dict[str, tuple[int, int, int]]:
    """``name -> (width, height, EXIF orientation)`` from the headers only (1 = upright)."""
    from PIL import Image

    info = {}
    for p in paths:
        with Image.open(p) as im:
            info[p.name] = (im.width, im.height, int(im.getexif().get(0x0112, 1) or 1))
    return info


def report_unreadable(bad: list[str], folder: Path, skip: bool) -> None:
    """Raise one error listing every unreadable file, or (``skip``) log a warning listing them."""
    if not bad:
        return
    listing = "\n  ".join(bad)
    if not skip:
        raise ValueError(f"{len(bad)} unreadable or corrupt image file(s) in {folder} "
                         f"(set skip_unreadable to ignore them):\n  {listing}")
    log.warning("skipping %d unreadable or corrupt image file(s) in %s:\n  %s", len(bad), folder, listing)


def screen_photos(paths: list[Path], folder: Path, skip: bool = False) -> list[Path]:
    """Photos that can take part in a capture, from readable ``paths``.

    - blank ones (black, white or one colour: luminance std below 2 levels of 255) are an error
      listing them (``skip``: a warning, and they are left out);
    - exact copies of an earlier photo (the same pixels at 64 px) are left out with a warning;
      fewer than :data:`MIN_IMAGES` distinct photos left is an error naming the copies;
    - a photo whose aspect ratio (orientation aside) differs by more than 5% from the capture's
      median (a panorama, a crop, a screenshot, a 10,000 px wide stitch) is an error naming it and
      its size, since one camera cannot describe it.
    """
    import numpy as np
    from PIL import Image, ImageOps

    thumbs, aspects, blank = {}, {}, []
    for p in paths:
        im = ImageOps.exif_transpose(_decode(p)).convert("L")
        aspects[p] = max(im.size) / max(min(im.size), 1)
        im.thumbnail((64, 64), Image.Resampling.BILINEAR)
        arr = np.asarray(im, np.float32)
        if arr.std() < 2.0:
            blank.append(p)
        thumbs[p] = arr
    if blank:
        listing = ", ".join(q.name for q in blank)
        if not skip:
            raise ValueError(f"{len(blank)} blank photo(s) in {folder} (black, white or one colour; set "
                             f"skip_unreadable to leave them out): {listing}")
        log.warning("leaving out %d blank photo(s) in %s: %s", len(blank), folder, listing)
    keep, copies, seen = [], [], {}
    for p in paths:
        if p in blank:
            continue
        key = (thumbs[p].shape, thumbs[p].tobytes())
        if key in seen:
            copies.append(f"{p.name} = {seen[key].name}")
            continue
        seen[key] = p
        keep.append(p)
    if copies:
        log.warning("leaving out %d copies of other photos in %s: %s", len(copies), folder, ", ".join(copies))
    if len(keep) < MIN_IMAGES:
        raise ValueError(f"only {len(keep)} distinct photo(s) in {folder} (a capture needs at least {MIN_IMAGES} "
                         f"photos from different viewpoints); copies: {', '.join(copies) or 'none'}")
    median = float(np.median([aspects[p] for p in keep]))
    odd = [p for p in keep if abs(aspects[p] / median - 1) > 0.05]
    if odd:
        sizes = ", ".join(f"{p.name} ({_size(p)})" for p in odd)
        raise ValueError(f"{len(odd)} photo(s) in {folder} have another shape than the capture's (aspect "
                         f"{median:.3f}): {sizes}; a panorama, crop or screenshot cannot share the photos' "
                         "camera: remove it")
    return keep


def _size(path: Path) -> str:
    from PIL import Image

    with Image.open(path) as im:
        return f"{im.width}x{im.height}"


def require_min_images(n: int, folder: Path, what: str = "readable images") -> None:
    if n < MIN_IMAGES:
        raise ValueError(f"need at least {MIN_IMAGES} {what} in {folder}, found {n}")


def import_photos(src_dir: str | Path, dst_dir: str | Path, max_side: int | None = None,
                  skip_unreadable: bool = False, screen: bool = True) -> list[str]:
    """Copy JPEG/PNG photos from ``src_dir`` to ``dst_dir`` as upright RGB PNGs.

    Args:
        src_dir: folder with the user's photos (not searched recursively).
        dst_dir: output folder; ``<stem>.png`` per photo, written atomically. Image files
            already there that this import does not write are removed (with a log line)
            so a later stage never sees stale photos.
        max_side: if given, photos whose longest side exceeds it are downscaled
            (Lanczos, aspect ratio kept) so the longest side equals ``max_side``.
        skip_unreadable: skip corrupt (and blank) files with a warning listing them instead of failing.
        screen: check that the photos can form a capture (:func:`screen_photos`: blank photos,
            copies, odd shapes); off only to convert single images.

    Returns:
        The written file names, sorted.
    """
    from PIL import Image, ImageOps

    src_dir, dst_dir = Path(src_dir), Path(dst_dir)
    if max_side is not None and int(max_side) < 1:
        raise ValueError(f"max_side must be a positive integer or None, got {max_side!r}")
    files = list_images(src_dir)
    stems: dict[str, Path] = {}
    for p in files:
        key = p.stem.lower()
        if key in stems:
            raise ValueError(f"photos {stems[key].name} and {p.name} in {src_dir} would both be written "
                             f"as {p.stem}.png; rename one")
        stems[key] = p
    good, bad = check_images(files)  # decode everything first: fail before writing anything
    report_unreadable(bad, src_dir, skip_unreadable)
    require_min_images(len(good), src_dir, "readable photos")
    if screen:
        good = screen_photos(good, src_dir, skip_unreadable)

    dst_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for p in good:  # decode again one at a time: never hold all photos in memory
        im = ImageOps.exif_transpose(_decode(p))
        if im.mode != "RGB":
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                im = im.convert("RGBA")
                bg = Image.new("RGBA", im.size, (255, 255, 255, 255))
                im = Image.alpha_composite(bg, im)
            elif im.mode.startswith("I;16") or im.mode == "I":
                im = im.point(lambda v: v / 256).convert("L")
            im = im.convert("RGB")
        if max_side is not None and max(im.size) > int(max_side):
            f = int(max_side) / max(im.size)
            size = (max(1, round(im.width * f)), max(1, round(im.height * f)))
            im = im.resize(size, Image.Resampling.LANCZOS)
        name = f"{p.stem}.png"
        with atomic_path(dst_dir / name) as tmp:
            im.save(tmp, format="PNG")
        written.append(name)
    stale = sorted(q.name for q in dst_dir.iterdir()
                   if q.is_file() and q.suffix.lower() in IMAGE_SUFFIXES and q.name not in written)
    if stale:
        log.info("removing %d stale image(s) from %s: %s", len(stale), dst_dir, ", ".join(stale))
        for n in stale:
            (dst_dir / n).unlink()
    log.info("imported %d photo(s) from %s into %s%s", len(written), src_dir, dst_dir,
             f" (longest side <= {max_side})" if max_side else "")
    return sorted(written)
