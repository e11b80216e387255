"""For ``benchmarks/gpu_check.sh`` only: the demo's mp4s written with OpenCV where imageio-ffmpeg is missing.

The lent GPU machine reaches no package registry, and imageio-ffmpeg's wheel (an ffmpeg binary,
68 MB) does not fit in the 64 MiB that travel with the check. ``gpu_check.sh`` puts this folder on
``PYTHONPATH`` and sets ``ANIGS_GPU_CHECK_MP4_SHIM=1``; Python then imports this file at start-up
(``sitecustomize``) in every process, the workflow's jobs included. Only when imageio-ffmpeg is
not installed, it replaces ``anigs.video.write_mp4`` (once ``anigs.video`` is imported) by a writer
using OpenCV's MPEG-4 Part 2 encoder (``mp4v``): the same frames and file names, another codec
(H.264 needs ffmpeg's libx264). Each replaced write is logged on stderr. Nothing else changes.
"""
from __future__ import annotations

import importlib.abc
import importlib.util
import os
import sys


def write_mp4_opencv(path, clip, fps: int = 24, quality: int = 8) -> None:
    """Write frames [T,H,W,3] in [0,1] to ``path`` as an MPEG-4 Part 2 mp4 (OpenCV), atomically."""
    import cv2

    from anigs.io import atomic_path
    from anigs.video import check_clip, to_uint8

    frames = to_uint8(check_clip(clip))
    _, height, width, _ = frames.shape
    with atomic_path(path) as tmp:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (width, height))
        if not writer.isOpened():
            raise RuntimeError(f"{path}: OpenCV could not open an mp4v writer (imageio-ffmpeg is not installed "
                               "on this machine either)")
        for f in frames:
            writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        writer.release()
    print(f"[gpu-check shim] {path}: mp4 written with OpenCV (mp4v), imageio-ffmpeg is not installed",
          file=sys.stderr)


class _PatchVideo(importlib.abc.MetaPathFinder):
    """Finds ``anigs.video`` through the other finders, then swaps ``write_mp4`` after it executes."""

    def find_spec(self, name, path=None, target=None):
        if name != "anigs.video":
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            module.write_mp4 = write_mp4_opencv

        spec.loader.exec_module = exec_module
        return spec


if os.environ.get("ANIGS_GPU_CHECK_MP4_SHIM") == "1" and importlib.util.find_spec("imageio_ffmpeg") is None:
    sys.meta_path.insert(0, _PatchVideo())
