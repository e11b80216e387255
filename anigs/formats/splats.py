"""Splat files of any tool: the PLY forms (plain 3DGS or SuperSplat's compressed one, with the
quantisation step of each position: :func:`load_splats`) and every format anigs reads
(:func:`read_splat_file`: PLY, SPZ, glb, antimatter15's ``.splat``).

``.splat`` (antimatter15/splat, also written by SuperSplat and splat-transform): no header, 32 bytes
per Gaussian: position (3 float32), linear scale (3 float32), colour RGBA (4 uint8: ``0.5 + C0 f_dc``
and the opacity after the sigmoid, times 255) and rotation (4 uint8: ``128 q + 128`` of the unit
quaternion w, x, y, z).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from anigs.formats.compressed_ply import is_compressed_ply, read_compressed_ply
from anigs.formats.gltf import load_glb
from anigs.formats.spz import load_spz
from anigs.gaussians import SH_C0, Gaussians, load_ply

SPLAT_RECORD = np.dtype([("position", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])
#: suffix -> format name of :func:`read_splat_file`
SUFFIXES = {".ply": "ply", ".spz": "spz", ".glb": "glb", ".splat": "splat"}


def load_splats(path: str | Path) -> tuple[Gaussians, np.ndarray, str]:
    """The Gaussians of ``path``, the quantisation step [N,3] of each position (zero for float
    positions) and the layout's name (``ply`` or ``compressed ply``)."""
    if is_compressed_ply(path):
        g, step = read_compressed_ply(path)
        return g, step, "compressed ply"
    g = load_ply(path)
    return g, np.zeros((g.num, 3)), "ply"


def load_splat(path: str | Path) -> Gaussians:
    """The Gaussians of an antimatter15 ``.splat`` file (32-byte records, see the module docstring)."""
    path = Path(path)
    raw = path.read_bytes()
    if len(raw) % SPLAT_RECORD.itemsize:
        raise ValueError(f"{path}: {len(raw)} bytes is not a whole number of 32-byte .splat records")
    rec = np.frombuffer(raw, SPLAT_RECORD)
    q = (rec["rot"].astype(np.float64) - 128) / 128
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 0, q / np.where(norm > 0, norm, 1), np.array([1.0, 0.0, 0.0, 0.0]))
    rgba = rec["rgba"].astype(np.float64) / 255
    alpha = np.clip(rgba[:, 3], 1e-6, 1 - 1e-6)
    scale = np.maximum(rec["scale"].astype(np.float64), np.finfo(np.float32).tiny)
    f32 = lambda a: torch.from_numpy(np.ascontiguousarray(a, np.float32))
    return Gaussians(f32(rec["position"]), f32(q), f32(np.log(scale)), f32(np.log(alpha / (1 - alpha))),
                     f32(((rgba[:, :3] - 0.5) / SH_C0)[:, None]))


def _sniff(path: Path) -> str | None:
    """The format of ``path`` from its first bytes (``None``: no magic; a ``.splat`` has none)."""
    with open(path, "rb") as fh:
        head = fh.read(4)
    if head == b"glTF":
        return "glb"
    if head[:3] == b"ply":
        return "ply"
    if head == b"NGSP" or head[:2] == b"\x1f\x8b":
        return "spz"
    return None


def read_splat_file(path: str | Path) -> tuple[Gaussians, str]:
    """The Gaussians of a splat file and its format's name (``ply``, ``compressed ply``, ``spz``,
    ``glb`` or ``splat``), by the suffix or, for another suffix, the file's first bytes. A glb is read
    as stored (``load_glb(apply_nodes=False)``: anigs's frame for anigs's files)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"splat file not found: {path}")
    fmt = SUFFIXES.get(path.suffix.lower()) or _sniff(path)
    if fmt is None:
        raise ValueError(f"{path}: unknown splat format (suffix {path.suffix!r}); supported: "
                         f"{', '.join(SUFFIXES)} (PLY plain or compressed, SPZ v2-v4, glb with KHR_gaussian_splatting, "
                         "antimatter15 .splat)")
    if fmt == "ply":
        g, _, fmt = load_splats(path)
        return g, fmt
    readers = {"spz": load_spz, "glb": load_glb, "splat": load_splat}
    return readers[fmt](path), fmt
