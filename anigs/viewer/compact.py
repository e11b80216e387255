"""Compact animated 3DGS: canonical Gaussians once, DCT motion only for the dynamic ones.

File layout (``anigs-compact/1``, all numbers little-endian)::

    offset  size  field
    0       8     magic  b"ANIGSCMP"
    8       4     uint32 version (1)
    12      4     uint32 H: byte length of the JSON header (space-padded so 16 + H is a multiple of 16)
    16      H     UTF-8 JSON header
    16+H    ...   data section: the arrays, each starting at a multiple of 16 bytes

The header holds ``format``, ``num_gaussians`` N, ``sh_degree``, ``num_frames`` T,
``num_bases`` K, ``num_dynamic`` D, ``rotation``, ``fps``, ``data_bytes``, ``crc32`` (zlib CRC-32
of the data section) and ``arrays``: name -> ``{"dtype", "shape", "offset", "nbytes"}`` with
``offset`` relative to the data section. Arrays (C order, raw parameters as in
:class:`anigs.gaussians.Gaussians`, not activated)::

    means [N,3] <f4   quats [N,4] <f4 (w,x,y,z)   log_scales [N,3] <f4   opacity_logits [N] <f4
    sh [N,C,3] <f4 (C = (deg+1)^2, sh[:,0] the DC term)
    dynamic_index [D] <u4 (rows that move; every other row is still at every t)
    pos_coeffs [D,3,K] <f4   rot_coeffs [D,3,K] <f4 (only when rotation)
    max_offset [D] <f4, max_angle [D] <f4 (only when the model has the smooth limits)

The motion is :class:`anigs.animate.deform.DCTDeformation` (formula in ``header["formula"]``):
the loader rebuilds the same tensors, so frame t equals the library's frame t bit for bit.
"""
from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from anigs.animate.deform import DCTDeformation
from anigs.animate.frames import deformed
from anigs.export import FORMULA
from anigs.gaussians import Gaussians, sh_degree_from_coeffs
from anigs.io import atomic_path

MAGIC = b"ANIGSCMP"
VERSION = 1
FORMAT = "anigs-compact/1"
ALIGN = 16
_PREFIX = struct.Struct("<8sII")


class CompactFormatError(ValueError):
    """The file is not a valid (or is a truncated / corrupted) compact animated scene."""


@dataclass
class CompactScene:
    """A loaded compact scene: canonical Gaussians [N], the DCT field (D dynamic rows), the header."""

    canonical: Gaussians
    deformation: DCTDeformation
    header: dict[str, Any]

    def frame(self, t: float | torch.Tensor) -> Gaussians:
        """Gaussians at frame t (fractional allowed), exactly as :func:`anigs.animate.frames.deformed`."""
        return deformed(self.canonical, self.deformation, t)


def _arrays(canonical: Gaussians, deformation: DCTDeformation) -> dict[str, np.ndarray]:
    g = canonical.detach().to("cpu")
    f4 = lambda x: np.ascontiguousarray(x.detach().cpu().numpy().astype("<f4"))
    out = {"means": f4(g.means), "quats": f4(g.quats), "log_scales": f4(g.log_scales),
           "opacity_logits": f4(g.opacity_logits), "sh": f4(g.sh),
           "dynamic_index": np.ascontiguousarray(deformation.dynamic_index.cpu().numpy().astype("<u4")),
           "pos_coeffs": f4(deformation.pos_coeffs)}
    for name in ("rot_coeffs", "max_offset", "max_angle"):
        val = getattr(deformation, name)
        if val is not None:
            out[name] = f4(val)
    return out


def encode_compact(canonical: Gaussians, deformation: DCTDeformation, fps: float = 12.0,
                   extra: dict[str, Any] | None = None) -> bytes:
    """The compact file as bytes (see the module docstring for the layout)."""
    if deformation.num_gaussians is not None and deformation.num_gaussians != canonical.num:
        raise ValueError(f"deformation built for {deformation.num_gaussians} Gaussians, canonical has {canonical.num}")
    canonical.check_finite("compact export")
    if deformation.dynamic_index.numel() and int(deformation.dynamic_index.max()) >= canonical.num:
        raise ValueError("compact export: dynamic_index out of range of the canonical scene")
    arrays = _arrays(canonical, deformation)
    table, chunks, off = {}, [], 0
    for name, arr in arrays.items():
        pad = (-off) % ALIGN
        chunks.append(b"\0" * pad)
        off += pad
        table[name] = {"dtype": arr.dtype.str, "shape": list(arr.shape), "offset": off, "nbytes": arr.nbytes}
        chunks.append(arr.tobytes())
        off += arr.nbytes
    data = b"".join(chunks)
    header = {
        "format": FORMAT, "num_gaussians": canonical.num, "sh_degree": canonical.sh_degree,
        "num_frames": deformation.num_frames, "num_bases": deformation.num_bases,
        "num_dynamic": deformation.num_dynamic, "rotation": deformation.rot_coeffs is not None,
        "fps": float(fps), "data_bytes": len(data), "crc32": zlib.crc32(data), "arrays": table,
        "formula": dict(FORMULA, limits="with max_offset/max_angle: offset x -> L tanh(|x|/L) x/|x| "
                        "(rotation vector likewise) before use"),
        "extra": dict(extra or {}),
    }
    text = json.dumps(header, sort_keys=True).encode("utf-8")
    text += b" " * ((-(_PREFIX.size + len(text))) % ALIGN)
    return _PREFIX.pack(MAGIC, VERSION, len(text)) + text + data


def save_compact(path: str | Path, canonical: Gaussians, deformation: DCTDeformation, fps: float = 12.0,
                 extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write the compact file atomically; returns its header."""
    blob = encode_compact(canonical, deformation, fps, extra)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(blob)
    return parse_header(blob)[0]


def parse_header(blob: bytes | memoryview, where: str = "compact scene") -> tuple[dict[str, Any], int]:
    """(header, start of the data section) of a compact file's bytes; checks magic, version, length."""
    if len(blob) < _PREFIX.size:
        raise CompactFormatError(f"{where}: {len(blob)} bytes is too short for an anigs compact scene")
    magic, version, hlen = _PREFIX.unpack_from(blob, 0)
    if magic != MAGIC:
        raise CompactFormatError(f"{where}: not an anigs compact scene (magic {magic!r}, expected {MAGIC!r})")
    if version != VERSION:
        raise CompactFormatError(f"{where}: compact format version {version} is not supported (this is {VERSION})")
    start = _PREFIX.size + hlen
    if len(blob) < start:
        raise CompactFormatError(f"{where}: truncated in the header ({len(blob)} of {start} bytes)")
    try:
        header = json.loads(bytes(blob[_PREFIX.size:start]).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CompactFormatError(f"{where}: unreadable JSON header ({exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise CompactFormatError(f"{where}: header format is not {FORMAT!r}")
    need = start + int(header.get("data_bytes", 0))
    if len(blob) < need:
        raise CompactFormatError(f"{where}: truncated file ({len(blob)} of {need} bytes)")
    return header, start


def _array(blob: bytes | memoryview, start: int, header: dict, name: str, where: str) -> np.ndarray | None:
    spec = header["arrays"].get(name)
    if spec is None:
        return None
    dtype = np.dtype(spec["dtype"])
    shape = tuple(int(s) for s in spec["shape"])
    off, nbytes = int(spec["offset"]), int(spec["nbytes"])
    if nbytes != dtype.itemsize * int(np.prod(shape)) or off < 0 or off + nbytes > int(header["data_bytes"]):
        raise CompactFormatError(f"{where}: array {name!r} has an inconsistent size or offset")
    return np.frombuffer(blob, dtype=dtype, count=int(np.prod(shape)), offset=start + off).reshape(shape)


def decode_compact(blob: bytes | memoryview, where: str = "compact scene") -> CompactScene:
    """Rebuild (canonical, deformation) from a compact file's bytes."""
    header, start = parse_header(blob, where)
    data = memoryview(blob)[start:start + int(header["data_bytes"])]
    if zlib.crc32(data) != int(header.get("crc32", -1)):
        raise CompactFormatError(f"{where}: data section is corrupted (CRC-32 mismatch)")
    n, K, D = int(header["num_gaussians"]), int(header["num_bases"]), int(header["num_dynamic"])
    want = {"means": (n, 3), "quats": (n, 4), "log_scales": (n, 3), "opacity_logits": (n,),
            "dynamic_index": (D,), "pos_coeffs": (D, 3, K)}
    if header["rotation"]:
        want["rot_coeffs"] = (D, 3, K)
    arr: dict[str, np.ndarray | None] = {}
    for name in list(want) + ["sh", "max_offset", "max_angle"]:
        arr[name] = _array(blob, start, header, name, where)
    for name, shape in want.items():
        if arr[name] is None or arr[name].shape != shape:
            got = None if arr[name] is None else arr[name].shape
            raise CompactFormatError(f"{where}: array {name!r} has shape {got}, expected {shape}")
    sh = arr["sh"]
    if sh is None or sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3:
        raise CompactFormatError(f"{where}: array 'sh' missing or not [N,C,3]")
    if sh_degree_from_coeffs(sh.shape[1]) != int(header["sh_degree"]):
        raise CompactFormatError(f"{where}: sh has {sh.shape[1]} coefficients, header says degree {header['sh_degree']}")
    t = lambda a: torch.from_numpy(a.astype(np.float32))  # astype copies: tensors own their memory
    canonical = Gaussians(t(arr["means"]), t(arr["quats"]), t(arr["log_scales"]), t(arr["opacity_logits"]), t(sh))
    canonical.check_finite(where)
    lim = lambda a: None if a is None else t(a)
    deformation = DCTDeformation(torch.from_numpy(arr["dynamic_index"].astype(np.int64)), int(header["num_frames"]),
                                 K, bool(header["rotation"]), lim(arr["max_offset"]), lim(arr["max_angle"]), n)
    with torch.no_grad():
        deformation.pos_coeffs.copy_(t(arr["pos_coeffs"]))
        if deformation.rot_coeffs is not None:
            deformation.rot_coeffs.copy_(t(arr["rot_coeffs"]))
    for name in ("pos_coeffs", "rot_coeffs"):
        p = getattr(deformation, name)
        if p is not None and not bool(torch.isfinite(p).all()):
            raise CompactFormatError(f"{where}: {name} has non-finite values")
    return CompactScene(canonical, deformation, header)


def load_compact(path: str | Path) -> CompactScene:
    """Read a compact file (clear :class:`CompactFormatError` on a bad, truncated or corrupted file)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"compact scene not found: {path}")
    return decode_compact(path.read_bytes(), str(path))


def write_frame_plys(out_dir: str | Path, canonical: Gaussians, deformation: DCTDeformation,
                     frame_step: int = 1) -> list[str]:
    """The optional per-frame 3DGS PLYs ``frames/frame_{t:04d}.ply`` (t = 0, step, ... < T); relative names.

    Frame t is :func:`anigs.animate.frames.deformed` written with :meth:`Gaussians.save_ply`, the
    same code as the PLY-sequence export.
    """
    if frame_step < 1:
        raise ValueError(f"frame_step must be >= 1, got {frame_step}")
    names = []
    with torch.no_grad():
        for t in range(0, deformation.num_frames, frame_step):
            name = f"frames/frame_{t:04d}.ply"
            deformed(canonical, deformation, t).save_ply(Path(out_dir) / name)
            names.append(name)
    return names
