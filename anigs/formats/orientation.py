"""The frames other splat tools show anigs's scene in, and how to stand it upright there.

anigs writes every splat file in its world frame: right-handed, metres on the demo, **+z up**
(ground near z = 0). Tools assume other habits:

- SuperSplat (and the SuperSplat viewer) turns a loaded PLY 180 degrees about z, so the positions
  it shows (and the box corners a user reads off it) are (-x, -y, z) of anigs's frame; its exports
  undo that turn. splat-transform's ``-B`` box filter works in the same SuperSplat frame.
- glTF, three.js (Spark), PlayCanvas and Babylon.js are +y up: a rotation of -90 degrees about x
  takes anigs's +z to their +y (x stays, y -> -z, z -> y).

``README.md`` ("Opening the exports in other tools") states the same per tool; a test reads it back.
"""
from __future__ import annotations

import math

import numpy as np

#: [3,3] SuperSplat's displayed frame from anigs's: (x, y, z) -> (-x, -y, z) (its own inverse)
SUPERSPLAT = np.diag([-1.0, -1.0, 1.0])
#: [3,3] a -90 degree rotation about x: anigs's +z up becomes +y up (glTF, three.js, PlayCanvas)
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: the same rotation as a glTF node quaternion (x, y, z, w)
Y_UP_QUAT_XYZW = (-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))
#: box corners and points may be given in these frames (``effects.boxes[].frame``)
FRAMES = {"anigs": np.eye(3), "supersplat": SUPERSPLAT}


def to_anigs(points: np.ndarray, frame: str) -> np.ndarray:
    """Points [..., 3] given in ``frame`` (a key of :data:`FRAMES`) in anigs's world frame."""
    if frame not in FRAMES:
        raise ValueError(f"unknown frame {frame!r}: choose one of {list(FRAMES)}")
    return np.asarray(points, float) @ FRAMES[frame]  # every frame matrix is orthogonal and symmetric


def box_to_anigs(lo: np.ndarray, hi: np.ndarray, frame: str) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned box with corners ``lo``, ``hi`` [3] in ``frame``, in anigs's frame (min, max)."""
    a, b = to_anigs(lo, frame), to_anigs(hi, frame)
    return np.minimum(a, b), np.maximum(a, b)
