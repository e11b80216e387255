"""Atomic artifact writes: write to a temporary name in the same folder, then rename.

An interrupted job therefore never leaves a half-written artifact under its final name.
A library writer that fills a stage's folder takes it as a :class:`StageFolder` (the stage's ``Outputs``),
so the file names stay with the stage.
"""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Protocol

import numpy as np


class StageFolder(Protocol):
    """A stage's output folder as a library writer sees it (:class:`anigs.contract.Outputs`):
    its ``root`` and ``path(key, **fields)`` of each file; the names are the stage's."""

    root: Path

    def path(self, key: str, **fields: Any) -> Path: ...


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    The temporary name keeps the suffix so libraries that dispatch on it still work.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def atomic_write_text(path: str | Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None if np.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


def write_json(path: str | Path, data: Any) -> None:
    """Atomically write JSON (numpy values converted; NaN written as null)."""
    atomic_write_text(path, json.dumps(_jsonable(data), indent=1))


def read_json(path: str | Path) -> Any:
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"file not found: {path}")
    return json.loads(path.read_text())


def write_npz(path: str | Path, compress: bool = True, **arrays: np.ndarray) -> None:
    """Atomically write an npz (deflated, or with ``compress=False`` stored), byte-for-byte reproducible.

    ``np.savez_compressed`` stamps each member with the current time; here every member gets
    a fixed timestamp, so the same arrays always give the same file (a run on a cluster can be
    compared with a local run bit for bit). ``np.load`` reads it as usual.
    """
    import io
    import zipfile

    with atomic_path(path) as tmp:
        method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
        with zipfile.ZipFile(tmp, "w", compression=method) as zf:
            for name, value in arrays.items():
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
                info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = method
                zf.writestr(info, buf.getvalue())
