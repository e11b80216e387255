"""A model update's target clip read from disk a frame at a time (:class:`ClipFrames`).

The update samples a few (view, frame) pairs per step; holding every target clip of a round as
float32 costs V x T x H x W x 3 x 4 bytes (24 views of 121 frames at 1024x768: 27 GB). A clip
``.npz`` of :func:`anigs.video.save_clip` stores its ``frames`` member uncompressed, so one frame is
one contiguous read at a known offset: :class:`ClipFrames` keeps only that offset and reads the
frames a step asks for, converted to float32 exactly as :func:`anigs.video.load_clip` converts the
whole clip (float16 -> float32 is exact: the same values bit for bit). A deflated or
Fortran-ordered member (an older file) cannot be read in place: it is held as stored (float16:
half the bytes of float32).
"""
from __future__ import annotations

import json
import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

_LOCAL_HEADER = struct.Struct("<4s5H3L2H")  # a zip member's local file header (30 bytes)
_HEADERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}


def _member_offset(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path) -> int:
    """Byte offset in the file of a stored member's first data byte (after its local header)."""
    with open(path, "rb") as f:
        f.seek(info.header_offset)
        fields = _LOCAL_HEADER.unpack(f.read(_LOCAL_HEADER.size))
    if fields[0] != b"PK\x03\x04":
        raise ValueError(f"{path}: member {info.filename} has no local zip header")
    return info.header_offset + _LOCAL_HEADER.size + fields[-2] + fields[-1]


class ClipFrames:
    """The frames of one clip ``.npz`` [T,H,W,3], read on demand.

    ``clip[t]`` -> float32 tensor [H,W,3] (a fresh copy, the values :func:`anigs.video.load_clip`
    gives); ``shape``, ``ndim`` and ``meta`` as for the loaded clip. ``held_bytes``: the frame data
    kept in memory (0 when read in place)."""

    def __init__(self, path: str | Path) -> None:
        self.path = p = Path(path)
        if not p.exists():
            raise FileNotFoundError(f"clip not found: {p}")
        self._held: np.ndarray | None = None
        with zipfile.ZipFile(p) as zf:
            names = zf.namelist()
            if "frames.npy" not in names:
                raise ValueError(f"{p}: not a clip .npz (no 'frames' member; members: {names})")
            self.meta: dict[str, Any] = {}
            if "meta.npy" in names:
                with zf.open("meta.npy") as f:
                    self.meta = json.loads(str(np.lib.format.read_array(f, allow_pickle=False)))
            info = zf.getinfo("frames.npy")
            with zf.open(info) as f:
                version = np.lib.format.read_magic(f)
                read_header = _HEADERS.get(version)
                shape, fortran, dtype = read_header(f) if read_header else ((), True, None)
                header = f.tell()
                if info.compress_type != zipfile.ZIP_STORED or fortran:
                    f.seek(0)
                    self._held = np.lib.format.read_array(f, allow_pickle=False)
                    shape, dtype = self._held.shape, self._held.dtype
            self._offset = _member_offset(zf, info, p) + header
            data_bytes = info.file_size - header
        self.shape, self.dtype = tuple(int(s) for s in shape), np.dtype(dtype)
        if len(self.shape) != 4 or self.shape[-1] != 3:
            raise ValueError(f"{p}: expected [T,H,W,3], got {self.shape}")
        if self.shape[0] < 1:
            raise ValueError(f"{p}: has no frames")
        self._frame_bytes = int(np.prod(self.shape[1:])) * self.dtype.itemsize
        if self._held is None and data_bytes != self.shape[0] * self._frame_bytes:
            raise ValueError(f"{p}: its frames member holds {data_bytes} bytes of data, its header promises "
                             f"{self.shape} {self.dtype} ({self.shape[0] * self._frame_bytes} bytes)")
        self._check_finite()

    ndim = 4

    @property
    def held_bytes(self) -> int:
        return 0 if self._held is None else int(self._held.nbytes)

    def __len__(self) -> int:
        return self.shape[0]

    def _stored(self, t: int, f) -> np.ndarray:
        if self._held is not None:
            return self._held[t]
        f.seek(self._offset + t * self._frame_bytes)
        buf = f.read(self._frame_bytes)
        if len(buf) != self._frame_bytes:
            raise ValueError(f"{self.path}: frame {t} is cut short ({len(buf)} of {self._frame_bytes} bytes)")
        return np.frombuffer(buf, self.dtype).reshape(self.shape[1:])

    def _check_finite(self) -> None:
        """Every frame finite (what :func:`anigs.video.check_clip` checks), read one frame at a time."""
        with open(self.path, "rb") as f:
            for t in range(self.shape[0]):
                if not np.isfinite(self._stored(t, f)).all():
                    raise ValueError(f"{self.path}: contains NaN or Inf (frame {t})")

    def __getitem__(self, t: int) -> torch.Tensor:
        t = int(t)
        if not -self.shape[0] <= t < self.shape[0]:
            raise IndexError(f"{self.path}: frame {t} of {self.shape[0]}")
        t %= self.shape[0]
        with open(self.path, "rb") as f:
            return torch.from_numpy(self._stored(t, f).astype(np.float32))
