"""A similarity transform of 3D points and cameras: ``x_new = scale * R @ x_old + t`` (``scale`` > 0, ``R`` [3,3]
rotation, ``t`` [3]). A base type, read by the renderer's label frames, the SfM alignment and imported splats
(:mod:`anigs.sfm.align` fits one)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.cameras import Camera


@dataclass(frozen=True)
class Similarity:
    """``x_new = scale * R @ x_old + t``."""

    scale: float
    R: np.ndarray  # [3,3]
    t: np.ndarray  # [3]

    @staticmethod
    def identity() -> "Similarity":
        return Similarity(1.0, np.eye(3), np.zeros(3))

    def matrix(self) -> np.ndarray:
        """The transform as a [3,4] matrix ``[s R | t]``."""
        return np.c_[self.scale * self.R, self.t]

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform points [N,3] -> [N,3]."""
        return self.scale * np.asarray(points, dtype=np.float64) @ self.R.T + self.t

    def compose(self, first: "Similarity") -> "Similarity":
        """The similarity that applies ``first`` and then ``self``."""
        return Similarity(self.scale * first.scale, self.R @ first.R, self.scale * self.R @ first.t + self.t)

    def inverse(self) -> "Similarity":
        """The similarity that undoes this one."""
        return Similarity(1.0 / self.scale, self.R.T, -(self.R.T @ self.t) / self.scale)

    def apply_viewmat(self, viewmat: np.ndarray) -> np.ndarray:
        """World-to-camera [4,4] in the old world -> the same camera in the new world.

        The camera frame is scaled with the world, so the result stays rigid:
        ``R' = Rc R^T`` and ``t' = s tc - R' t``.
        """
        V = np.asarray(viewmat, dtype=np.float64)
        Rn = V[:3, :3] @ self.R.T
        out = np.eye(4)
        out[:3, :3] = Rn
        out[:3, 3] = self.scale * V[:3, 3] - Rn @ self.t
        return out

    def apply_camera(self, cam: Camera) -> Camera:
        return Camera(cam.K.copy(), self.apply_viewmat(cam.viewmat), cam.width, cam.height, cam.name)
