"""Any PLY a splat tool writes: the plain 3DGS layout or SuperSplat's compressed one."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from anigs.formats.compressed_ply import is_compressed_ply, read_compressed_ply
from anigs.gaussians import Gaussians, load_ply


def load_splats(path: str | Path) -> tuple[Gaussians, np.ndarray, str]:
    """The Gaussians of ``path``, the quantisation step [N,3] of each position (zero for float
    positions) and the layout's name (``ply`` or ``compressed ply``)."""
    if is_compressed_ply(path):
        g, step = read_compressed_ply(path)
        return g, step, "compressed ply"
    g = load_ply(path)
    return g, np.zeros((g.num, 3)), "ply"
