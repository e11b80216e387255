"""User photos: find them, check they decode, import them as upright PNGs.

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


def require_min_images(n: int, folder: Path, what: str = "readable images") -> None:
    if n < MIN_IMAGES:
        raise ValueError(f"need at least {MIN_IMAGES} {what} in {folder}, found {n}")


def import_photos(src_dir: str | Path, dst_dir: str | Path, max_side: int | None = None,
                  skip_unreadable: bool = False) -> list[str]:
    """Copy JPEG/PNG photos from ``src_dir`` to ``dst_dir`` as upright RGB PNGs.

    Args:
        src_dir: folder with the user's photos (not searched recursively).
        dst_dir: output folder; ``<stem>.png`` per photo, written atomically. Image files
            already there that this import does not write are removed (with a log line)
            so a later stage never sees stale photos.
        max_side: if given, photos whose longest side exceeds it are downscaled
            (Lanczos, aspect ratio kept) so the longest side equals ``max_side``.
        skip_unreadable: skip corrupt files with a warning listing them instead of failing.

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
