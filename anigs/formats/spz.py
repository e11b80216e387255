"""Niantic's SPZ (version 3: one gzip stream), written and read with numpy and the standard library.

Layout (the public spec and ``load-spz.cc`` of nianticlabs/spz): a 16-byte header (magic ``NGSP``,
version, number of points, SH degree, fractional bits, flags, reserved), then per attribute for all
points: positions (3 x 24-bit signed fixed point, ``fractional_bits`` = 12: 1/4096 steps), alphas
(8 bits of the sigmoid), colours (8 bits of ``0.5 + 0.15 f_dc``), scales (8 bits of
``(log s + 10) * 16``), rotations (the largest of x, y, z, w by 2 bits, the three others by a sign and
9 bits of ``|q| / sqrt(1/2)``), and the higher SH coefficients (8 bits of ``128 + 128 c``; degree 1
kept to 5 bits, degree 2 and 3 to 4 bits, as the library writes them). The writer writes version 3,
which splat-transform, Spark and gsply read.

The reader also takes version 2 (3-byte rotations) and version 4 (``NGSP_V4``, the reference's newest:
a 32-byte uncompressed header, optional extension records, a table of contents of 16 bytes per stream
(compressed and uncompressed size, u64), then each attribute block above as its own zstd stream, empty
ones left out). Version 4 needs the ``zstandard`` module (not a core dependency: ``pip install
zstandard``); its extension records (such as a coordinate-system tag) are skipped: the values are read
as stored, as for version 3.

Coordinates are written as they are (the library's ``UNSPECIFIED`` frame, as splat-transform
writes them): anigs's +z-up frame, the same as ``canonical.ply``, so the same rotation stands both
upright in a viewer (:mod:`anigs.formats.orientation`).
"""
from __future__ import annotations

import gzip
import math
import struct
from pathlib import Path

import numpy as np
import torch

from anigs.gaussians import Gaussians
from anigs.io import atomic_path

MAGIC = 0x5053474E
VERSION = 3
FRACTIONAL_BITS = 12
COLOR_SCALE = 0.15
SH_BITS = (5, 4, 4)  # per SH degree 1, 2, 3
NGSP_V4 = struct.Struct("<IIIBBBBI12x")  # magic, version, points, SH degree, fractional bits, flags, streams, TOC offset


def _u8(x: np.ndarray) -> np.ndarray:
    return np.clip(np.round(x), 0, 255).astype(np.uint8)


def _pack_quats(q_wxyz: np.ndarray) -> np.ndarray:
    """[N,4] uint8: smallest-three packing of unit quaternions (x, y, z, w order, little-endian)."""
    q = q_wxyz[:, [1, 2, 3, 0]].astype(np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 0, q / np.where(norm > 0, norm, 1), np.array([0.0, 0.0, 0.0, 1.0]))
    largest = np.abs(q).argmax(1)
    negate = q[np.arange(len(q)), largest] < 0
    comp = largest.astype(np.uint64)
    for i in range(4):
        keep = largest != i
        neg = ((q[:, i] < 0) ^ negate).astype(np.uint64)
        mag = np.floor(511 * np.abs(q[:, i]) / math.sqrt(0.5) + 0.5).astype(np.uint64)
        comp = np.where(keep, (comp << np.uint64(10)) | (neg << np.uint64(9)) | mag, comp)
    comp = comp.astype(np.uint32)
    return np.stack([(comp >> np.uint32(s)) & np.uint32(255) for s in (0, 8, 16, 24)], 1).astype(np.uint8)


def _unpack_quats(r: np.ndarray) -> np.ndarray:
    """[N,4] w, x, y, z of smallest-three packed rotations ``r`` [N,4] uint8."""
    comp = (r[:, 0].astype(np.uint32) | (r[:, 1].astype(np.uint32) << 8) | (r[:, 2].astype(np.uint32) << 16)
            | (r[:, 3].astype(np.uint32) << 24))
    largest = (comp >> np.uint32(30)).astype(int)
    q = np.zeros((len(r), 4))
    rest = comp.copy()
    for i in (3, 2, 1, 0):  # the last stored component sits in the lowest bits
        here = largest != i
        mag = (rest & np.uint32(511)).astype(np.float64) / 511 * math.sqrt(0.5)
        neg = ((rest >> np.uint32(9)) & np.uint32(1)).astype(bool)
        q[:, i] = np.where(here, np.where(neg, -mag, mag), q[:, i])
        rest = np.where(here, rest >> np.uint32(10), rest)
    rows = np.arange(len(r))
    q[rows, largest] = np.sqrt(np.clip(1 - (q ** 2).sum(1), 0, None))
    return q[:, [3, 0, 1, 2]]


def _quantise_sh(c: np.ndarray, bits: int) -> np.ndarray:
    q = np.round(c * 128.0).astype(np.int64) + 128
    bucket = 1 << (8 - bits)
    q = (q + bucket // 2) // bucket * bucket
    return np.clip(q, 0, 255).astype(np.uint8)


def spz_bytes(g: Gaussians) -> bytes:
    """The uncompressed SPZ v3 payload (header and attribute blocks) of ``g``."""
    g = g.detach().to("cpu")
    n, deg = g.num, g.sh_degree
    if deg > 3:
        raise ValueError(f"SPZ: SH degree {deg} not supported (at most 3)")
    means = g.means.double().numpy()
    fixed = np.round(means * (1 << FRACTIONAL_BITS)).astype(np.int64)
    if n and np.abs(fixed).max() >= 1 << 23:
        raise ValueError(f"SPZ: positions reach {np.abs(means).max():.1f}, beyond the 24-bit fixed point range "
                         f"(+-{(1 << 23) / (1 << FRACTIONAL_BITS):.0f} with {FRACTIONAL_BITS} fractional bits)")
    pos = (fixed & 0xFFFFFF).astype(np.uint32)
    pos = np.stack([(pos >> np.uint32(s)) & np.uint32(255) for s in (0, 8, 16)], -1).astype(np.uint8)  # [N,3,3]
    alpha = _u8(torch.sigmoid(g.opacity_logits.double()).numpy() * 255)
    colors = _u8(g.sh[:, 0].double().numpy() * (COLOR_SCALE * 255) + 0.5 * 255)
    scales = _u8((g.log_scales.double().numpy() + 10) * 16)
    rots = _pack_quats(g.quats.double().numpy())
    rest = g.sh[:, 1:].double().numpy()  # [N, C-1, 3]: coefficient-major, colour inner (the SPZ order)
    sh = np.zeros_like(rest, np.uint8)
    for d in range(1, deg + 1):
        a, b = d * d - 1, (d + 1) * (d + 1) - 1
        sh[:, a:b] = _quantise_sh(rest[:, a:b], SH_BITS[d - 1])
    header = np.array([MAGIC, VERSION, n], "<u4").tobytes() + bytes([deg, FRACTIONAL_BITS, 0, 0])
    return header + b"".join(np.ascontiguousarray(a).tobytes() for a in (pos, alpha, colors, scales, rots, sh))


def save_spz(path: str | Path, g: Gaussians) -> None:
    """Write ``g`` as an SPZ v3 file (gzip, deterministic: no time stamp in the gzip header)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(gzip.compress(spz_bytes(g), compresslevel=9, mtime=0))


def _block_sizes(n: int, deg: int, version: int) -> list[int]:
    """Bytes of the six attribute blocks (positions, alphas, colours, scales, rotations, SH)."""
    return [9 * n, n, 3 * n, 3 * n, (3 if version == 2 else 4) * n, 3 * ((deg + 1) ** 2 - 1) * n]


def _legacy_blocks(raw: bytes, path: Path) -> tuple[int, int, int, int, list[bytes]]:
    """(version, points, SH degree, fractional bits, blocks) of a gzip SPZ (versions 2 and 3)."""
    try:
        raw = gzip.decompress(raw)
    except (OSError, EOFError) as err:
        raise ValueError(f"{path}: not an SPZ file (neither NGSP nor a gzip stream: {err})") from None
    if len(raw) < 16:
        raise ValueError(f"{path}: not an SPZ file ({len(raw)} bytes after gzip)")
    magic, version, n = np.frombuffer(raw[:12], "<u4")
    deg, frac = raw[12], raw[13]
    if magic != MAGIC or version not in (2, 3) or deg > 3:
        raise ValueError(f"{path}: not an SPZ v2/v3 file (magic {magic:#x}, version {version}, SH degree {deg})")
    sizes = _block_sizes(int(n), deg, int(version))
    if len(raw) < 16 + sum(sizes):
        raise ValueError(f"{path}: truncated SPZ ({len(raw)} bytes, {16 + sum(sizes)} expected)")
    offsets = np.cumsum([16] + sizes)
    return int(version), int(n), deg, frac, [raw[o:o + s] for o, s in zip(offsets, sizes)]


def _v4_blocks(raw: bytes, path: Path) -> tuple[int, int, int, int, list[bytes]]:
    """(version, points, SH degree, fractional bits, blocks) of an SPZ version 4 (NGSP, zstd streams)."""
    if len(raw) < NGSP_V4.size:
        raise ValueError(f"{path}: SPZ version 4 header truncated ({len(raw)} of {NGSP_V4.size} bytes)")
    magic, version, n, deg, frac, _flags, streams, toc = NGSP_V4.unpack_from(raw)
    if version != 4:
        raise ValueError(f"{path}: NGSP header of version {version}; this reader takes SPZ version 4 "
                         "uncompressed headers (versions 2 and 3 are gzip files)")
    if deg > 3:
        raise ValueError(f"{path}: SPZ version 4 with SH degree {deg}; anigs reads degrees 0 to 3")
    try:
        import zstandard
    except ImportError:
        raise ValueError(f"{path}: SPZ version 4 is zstd-compressed and the zstandard module is missing: "
                         "pip install zstandard") from None
    sizes = _block_sizes(n, deg, version)
    kept = [i for i, s in enumerate(sizes) if s]
    if streams != len(kept) or toc < NGSP_V4.size or toc + 16 * streams > len(raw):
        raise ValueError(f"{path}: SPZ version 4 with {streams} streams at byte {toc} "
                         f"({len(kept)} expected, file {len(raw)} bytes)")
    blocks, off = [b""] * 6, toc + 16 * streams
    for k, i in enumerate(kept):
        packed, size = struct.unpack_from("<QQ", raw, toc + 16 * k)
        if size != sizes[i] or off + packed > len(raw):
            raise ValueError(f"{path}: SPZ version 4 stream {k}: {packed} bytes to {size} "
                             f"({sizes[i]} expected, file {len(raw)} bytes)")
        try:
            blocks[i] = zstandard.ZstdDecompressor().decompress(raw[off:off + packed], max_output_size=size)
        except zstandard.ZstdError as err:
            raise ValueError(f"{path}: SPZ version 4 stream {k} is not valid zstd: {err}") from None
        if len(blocks[i]) != size:
            raise ValueError(f"{path}: SPZ version 4 stream {k} holds {len(blocks[i])} bytes, {size} expected")
        off += packed
    return version, n, deg, frac, blocks


def load_spz(path: str | Path) -> Gaussians:
    """Read an SPZ file of version 2 or 3 (gzip) or 4 (zstd streams; needs ``pip install zstandard``)."""
    path = Path(path)
    raw = path.read_bytes()
    version, n, deg, frac, raw_blocks = (_v4_blocks if raw[:4] == b"NGSP" else _legacy_blocks)(raw, path)
    blocks = [np.frombuffer(b, np.uint8) for b in raw_blocks]
    n_rest = (deg + 1) ** 2 - 1
    p = blocks[0].reshape(n, 3, 3).astype(np.int64)
    fixed = p[..., 0] | (p[..., 1] << 8) | (p[..., 2] << 16)
    fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
    means = fixed / float(1 << frac)
    alpha = np.clip(blocks[1] / 255.0, 1e-6, 1 - 1e-6)
    dc = (blocks[2].reshape(n, 3) / 255.0 - 0.5) / COLOR_SCALE
    log_scales = blocks[3].reshape(n, 3) / 16.0 - 10
    if version == 2:
        xyz = blocks[4].reshape(n, 3) / 127.5 - 1
        quats = np.concatenate([np.sqrt(np.clip(1 - (xyz ** 2).sum(1, keepdims=True), 0, None)), xyz], 1)
    else:
        quats = _unpack_quats(blocks[4].reshape(n, 4))
    rest = (blocks[5].reshape(n, n_rest, 3).astype(np.float64) - 128) / 128
    f32 = lambda a: torch.from_numpy(np.ascontiguousarray(a, np.float32))
    return Gaussians(means=f32(means), quats=f32(quats), log_scales=f32(log_scales),
                     opacity_logits=f32(np.log(alpha / (1 - alpha))), sh=f32(np.concatenate([dc[:, None], rest], 1)))
