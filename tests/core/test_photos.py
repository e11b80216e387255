"""Photo import (anigs.photos): EXIF orientation, downscale, corrupt files, folder checks."""
from __future__ import annotations

import logging

import numpy as np
import pytest
from PIL import Image

from anigs.photos import check_images, import_photos, list_images


def _pattern(w: int, h: int, seed: int = 0) -> np.ndarray:
    """An asymmetric test image [h,w,3] uint8: random 8x8 blocks, left half darker, a red corner."""
    rng = np.random.default_rng(seed)
    blocks = rng.integers(100, 200, ((h + 7) // 8, (w + 7) // 8, 3), dtype=np.uint8)
    img = np.ascontiguousarray(np.repeat(np.repeat(blocks, 8, 0), 8, 1)[:h, :w])
    img[:, : w // 2] //= 4
    img[: h // 4, : w // 4] = (255, 0, 0)
    return img


def _save(path, arr, orientation: int | None = None, **kw):
    im = Image.fromarray(arr)
    if orientation is not None:
        exif = Image.Exif()
        exif[0x0112] = orientation
        kw["exif"] = exif
    im.save(path, **kw)


def _read(path) -> np.ndarray:
    with Image.open(path) as im:
        assert im.mode == "RGB"
        return np.asarray(im)


def test_import_honours_exif_orientation_and_writes_pngs(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    arr = _pattern(64, 32)
    _save(src / "a_plain.png", arr)
    _save(src / "b_rot.jpg", arr, orientation=6, quality=100)  # 6: display rotated 90 deg clockwise
    _save(src / "c_flip.JPG", arr, orientation=3, quality=100)  # 3: rotated 180 deg
    names = import_photos(src, dst)
    assert names == ["a_plain.png", "b_rot.png", "c_flip.png"]
    assert np.array_equal(_read(dst / "a_plain.png"), arr)  # PNG copy is lossless
    rot = _read(dst / "b_rot.png").astype(int)
    assert rot.shape == (64, 32, 3)  # portrait after honouring the tag
    expected = np.rot90(arr, k=-1).astype(int)  # clockwise
    assert np.abs(rot - expected).mean() < 4  # JPEG loss only
    assert np.abs(rot - np.rot90(arr, k=1).astype(int)).mean() > 20  # the other way round is wrong
    flip = _read(dst / "c_flip.png").astype(int)
    assert flip.shape == (32, 64, 3) and np.abs(flip - arr[::-1, ::-1].astype(int)).mean() < 4
    assert not [p for p in dst.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_downscale_to_max_side(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    _save(src / "wide.png", _pattern(300, 200))
    _save(src / "tall.png", _pattern(90, 240))
    _save(src / "small.png", _pattern(40, 30))
    import_photos(src, dst, max_side=120, screen=False)  # three shapes: conversion only, not a capture
    assert Image.open(dst / "wide.png").size == (120, 80)
    assert Image.open(dst / "tall.png").size == (45, 120)
    assert Image.open(dst / "small.png").size == (40, 30)  # never upscaled
    with pytest.raises(ValueError, match="max_side"):
        import_photos(src, dst, max_side=0)


def test_modes_are_converted_to_rgb(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    rgba = np.zeros((20, 30, 4), np.uint8)
    rgba[..., 0] = 200
    rgba[..., 3] = 255
    rgba[:, :10, 3] = 0  # transparent strip -> white
    Image.fromarray(rgba, "RGBA").save(src / "rgba.png")
    Image.fromarray(np.full((20, 30), 70, np.uint8), "L").save(src / "gray.png")
    Image.fromarray(np.full((20, 30), 40000, np.uint16)).save(src / "deep.png")
    import_photos(src, dst, screen=False)  # one-colour images: conversion only, not a capture
    out = _read(dst / "rgba.png")
    assert tuple(out[5, 20]) == (200, 0, 0) and tuple(out[5, 2]) == (255, 255, 255)
    assert tuple(_read(dst / "gray.png")[0, 0]) == (70, 70, 70)
    assert abs(int(_read(dst / "deep.png")[0, 0, 0]) - 40000 // 256) <= 1


def test_corrupt_files_listed_in_one_error_or_skipped(tmp_path, caplog):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    for i in range(3):
        _save(src / f"ok{i}.png", _pattern(32, 24, i))
    good = (src / "ok0.png").read_bytes()
    (src / "cut.png").write_bytes(good[: len(good) // 2])
    (src / "junk.jpeg").write_bytes(b"definitely not a jpeg")
    with pytest.raises(ValueError) as err:
        import_photos(src, dst)
    msg = str(err.value)
    assert "2 unreadable" in msg and "cut.png" in msg and "junk.jpeg" in msg and "skip_unreadable" in msg
    assert not dst.exists()  # nothing written before the check
    with caplog.at_level(logging.WARNING, logger="anigs.photos"):
        names = import_photos(src, dst, skip_unreadable=True)
    assert names == ["ok0.png", "ok1.png", "ok2.png"]
    assert "cut.png" in caplog.text and "junk.jpeg" in caplog.text
    good_paths, bad = check_images(list_images(src))
    assert len(good_paths) == 3 and len(bad) == 2


def test_folder_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing"):
        import_photos(tmp_path / "missing", tmp_path / "dst")
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("x")
    with pytest.raises(FileNotFoundError, match=str(empty)):
        import_photos(empty, tmp_path / "dst")
    two = tmp_path / "two"
    two.mkdir()
    _save(two / "a.png", _pattern(16, 16))
    _save(two / "b.png", _pattern(16, 16, 1))
    (two / "c.jpg").write_bytes(b"broken")
    with pytest.raises(ValueError, match="at least 3 readable photos.*found 2"):
        import_photos(two, tmp_path / "dst", skip_unreadable=True)


def test_name_collision_and_stale_files(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    dst.mkdir()
    for i in range(3):
        _save(src / f"p{i}.png", _pattern(16, 16, i))
    _save(dst / "old.png", _pattern(16, 16))
    (dst / "keep.txt").write_text("not an image")
    assert import_photos(src, dst) == ["p0.png", "p1.png", "p2.png"]
    assert not (dst / "old.png").exists() and (dst / "keep.txt").exists()
    _save(src / "p0.jpg", _pattern(16, 16))
    with pytest.raises(ValueError, match="p0.jpg.*p0.png|p0.png.*p0.jpg"):
        import_photos(src, dst)


def test_bad_captures_fail_early_naming_the_cause(tmp_path):
    """Blank photos, copies of one photo and an odd shape (a panorama among photos) stop the import
    before anything is written, each with an error that names the files; copies among enough
    distinct photos are left out with a warning."""
    def folder(name: str, arrays: dict) -> tuple:
        src = tmp_path / name / "src"
        src.mkdir(parents=True)
        for n, a in arrays.items():
            _save(src / n, a)
        return src, tmp_path / name / "dst"

    good = {f"p{i}.png": _pattern(64, 48, seed=i) for i in range(4)}
    src, dst = folder("blank", {**good, "black.png": np.zeros((48, 64, 3), np.uint8),
                                "white.png": np.full((48, 64, 3), 255, np.uint8)})
    with pytest.raises(ValueError, match=r"2 blank photo\(s\).*black.png, white.png"):
        import_photos(src, dst)
    assert not dst.exists()
    assert sorted(import_photos(src, dst, skip_unreadable=True)) == sorted(good)  # left out on request
    src, dst = folder("copies", {f"c{i:02d}.png": _pattern(64, 48, seed=7) for i in range(20)})
    with pytest.raises(ValueError, match=r"only 1 distinct photo.*c01.png = c00.png"):
        import_photos(src, dst)
    assert not dst.exists()
    src, dst = folder("some-copies", {**good, "again.png": _pattern(64, 48, seed=2)})
    names = import_photos(src, dst)  # the later of the two copies (by name) is left out
    assert len(names) == 4 and ("again.png" in names) != ("p2.png" in names)
    src, dst = folder("panorama", {**good, "pano.png": _pattern(640, 48, seed=9)})
    with pytest.raises(ValueError, match=r"pano.png \(640x48\).*remove it"):
        import_photos(src, dst)
    assert not dst.exists()
    src, dst = folder("two", {"a.png": _pattern(64, 48, 1), "b.png": _pattern(64, 48, 2)})
    with pytest.raises(ValueError, match="at least 3"):
        import_photos(src, dst)
    src, dst = folder("junk", {**good})
    (src / "notes.jpg").write_text("not a photo")
    (src / "cut.jpg").write_bytes((src / "p0.png").read_bytes()[:200])
    with pytest.raises(ValueError, match=r"(?s)2 unreadable.*cut.jpg: OSError.*notes.jpg"):
        import_photos(src, dst)

