"""Reader of the "compressed PLY" that SuperSplat exports (written by splat-transform's
``compressed-ply`` writer, which SuperSplat calls).

Layout (little-endian binary PLY), as the public sources of splat-transform describe it:

- ``element chunk ceil(N/256)``: float ``min_x min_y min_z max_x max_y max_z``, ``min_scale_*``,
  ``max_scale_*`` and (newer files) ``min_r min_g min_b max_r max_g max_b``: the bounds of each run of
  256 splats;
- ``element vertex N``: uint ``packed_position packed_rotation packed_scale packed_color``; a position
  is 11/10/11 bits (x, y, z) of its chunk's box, rounded to the nearest step; a scale (log) likewise;
  the rotation keeps the index of its largest component (2 bits) and the other three (10 bits each,
  in [-1/sqrt2, 1/sqrt2]); the colour is 8 bits per base colour (0.5 + C0 * f_dc) of its chunk's range
  and 8 bits of opacity (after the sigmoid);
- ``element sh N`` (optional): uchar ``f_rest_*`` in [-4, 4].

The position step of a splat is its chunk's extent over 2047 (x, z) or 1023 (y); the writer rounds,
so a position lies within half a step of the original.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from anigs.gaussians import SH_C0, Gaussians, read_ply_header

CHUNK = 256
BITS = (11, 10, 11)
_BOUNDS = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
           "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")
_PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")


def is_compressed_ply(path: str | Path) -> bool:
    """Whether ``path`` is a PLY whose first element is ``chunk`` (the compressed layout)."""
    with open(path, "rb") as fh:
        _, elements = read_ply_header(fh)
    return bool(elements) and elements[0][0] == "chunk"


def _unorm(v: np.ndarray, shift: int, bits: int) -> np.ndarray:
    return ((v >> np.uint32(shift)) & np.uint32((1 << bits) - 1)).astype(np.float64) / ((1 << bits) - 1)


def _unpack3(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """[N,3] values of 11/10/11-bit packed words ``v`` [N] in the boxes ``lo``, ``hi`` [N,3]."""
    t = np.stack([_unorm(v, 21, 11), _unorm(v, 11, 10), _unorm(v, 0, 11)], 1)
    return lo * (1 - t) + hi * t


def read_compressed_ply(path: str | Path) -> tuple[Gaussians, np.ndarray]:
    """The Gaussians of a compressed PLY and the quantisation step [N,3] of each position (world units)."""
    path = Path(path)
    with open(path, "rb") as fh:
        fmt, elements = read_ply_header(fh)
        body = fh.read()
    names = [e[0] for e in elements]
    if fmt != "binary_little_endian" or names[:2] != ["chunk", "vertex"]:
        raise ValueError(f"{path}: not a SuperSplat compressed PLY (format {fmt}, elements {names}; "
                         "expected binary_little_endian with 'chunk' then 'vertex')")
    arrays, offset = {}, 0
    for name, count, props in elements:
        if any(t == "list" for _, t in props):
            raise ValueError(f"{path}: list property in element {name!r}")
        dtype = np.dtype([(p, "<" + t) for p, t in props])
        if offset + dtype.itemsize * count > len(body):
            raise ValueError(f"{path}: truncated in element {name!r}")
        arrays[name] = np.frombuffer(body, dtype, count, offset)
        offset += dtype.itemsize * count
    chunk, vert = arrays["chunk"], arrays["vertex"]
    n = len(vert)
    missing = [p for p in _BOUNDS if p not in chunk.dtype.names] + [p for p in _PACKED if p not in vert.dtype.names]
    if missing:
        raise ValueError(f"{path}: compressed PLY without {missing}")
    if len(chunk) != (n + CHUNK - 1) // CHUNK:
        raise ValueError(f"{path}: {len(chunk)} chunks for {n} splats (expected {(n + CHUNK - 1) // CHUNK})")
    ci = np.arange(n) // CHUNK
    col = lambda *keys: np.stack([chunk[k].astype(np.float64) for k in keys], 1)[ci]
    lo, hi = col("min_x", "min_y", "min_z"), col("max_x", "max_y", "max_z")
    means = _unpack3(vert["packed_position"], lo, hi)
    step = (hi - lo) / np.array([(1 << b) - 1 for b in BITS], float)
    log_scales = _unpack3(vert["packed_scale"], col("min_scale_x", "min_scale_y", "min_scale_z"),
                          col("max_scale_x", "max_scale_y", "max_scale_z"))
    # rotation: the largest of (rot_0..rot_3) is rebuilt from the three stored ones
    pr = vert["packed_rotation"]
    three = np.stack([_unorm(pr, 20, 10), _unorm(pr, 10, 10), _unorm(pr, 0, 10)], 1)
    three = (three - 0.5) * np.sqrt(2.0)
    largest = (pr >> np.uint32(30)).astype(int)
    quats = np.empty((n, 4))
    rows = np.arange(n)
    quats[rows, largest] = np.sqrt(np.clip(1 - (three ** 2).sum(1), 0, None))
    others = np.array([[j for j in range(4) if j != k] for k in range(4)])[largest]  # [N,3]
    quats[rows[:, None], others] = three
    pc = vert["packed_color"]
    base = np.stack([_unorm(pc, 24, 8), _unorm(pc, 16, 8), _unorm(pc, 8, 8)], 1)
    if "min_r" in chunk.dtype.names:
        base = col("min_r", "min_g", "min_b") * (1 - base) + col("max_r", "max_g", "max_b") * base
    alpha = np.clip(_unorm(pc, 0, 8), 1e-6, 1 - 1e-6)
    rest = _sh_rest(arrays.get("sh"), n, path)
    sh = np.concatenate([((base - 0.5) / SH_C0)[:, None], rest], 1)
    g = Gaussians(means=torch.from_numpy(means.astype(np.float32)), quats=torch.from_numpy(quats.astype(np.float32)),
                  log_scales=torch.from_numpy(log_scales.astype(np.float32)),
                  opacity_logits=torch.from_numpy(np.log(alpha / (1 - alpha)).astype(np.float32)),
                  sh=torch.from_numpy(sh.astype(np.float32)))
    return g, step


def _sh_rest(sh: np.ndarray | None, n: int, path: Path) -> np.ndarray:
    """[N, C-1, 3] higher SH coefficients of the optional ``sh`` element (channel-major ``f_rest_*``)."""
    if sh is None:
        return np.zeros((n, 0, 3))
    names = sorted((p for p in sh.dtype.names if p.startswith("f_rest_")), key=lambda s: int(s.rsplit("_", 1)[1]))
    if len(names) not in (9, 24, 45) or len(sh) != n:
        raise ValueError(f"{path}: sh element with {len(names)} f_rest properties for {len(sh)} of {n} splats")
    b = np.stack([sh[p] for p in names], 1).astype(np.float64)
    v = np.where(b == 0, 0.0, np.where(b == 255, 1.0, (b + 0.5) / 256))
    return ((v - 0.5) * 8).reshape(n, 3, len(names) // 3).transpose(0, 2, 1)
