"""Pinhole cameras in the OpenCV convention (x right, y down, z forward).

A :class:`Camera` holds intrinsics ``K`` [3,3], the image size, and the
world-to-camera transform ``viewmat`` [4,4]. Pixel centres sit at integer + 0.5
(the COLMAP / gsplat convention), so ``cx = width / 2`` is the image centre.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch

from anigs.io import atomic_write_text


@dataclass
class Camera:
    """A pinhole camera.

    Attributes:
        K: intrinsics [3,3] (fx, fy, cx, cy), float64 numpy.
        viewmat: world-to-camera rigid transform [4,4], float64 numpy.
        width, height: image size in pixels.
        name: free-form identifier (image file name, view id).
    """

    K: np.ndarray
    viewmat: np.ndarray
    width: int
    height: int
    name: str = ""

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=np.float64).reshape(3, 3)
        self.viewmat = np.asarray(self.viewmat, dtype=np.float64).reshape(4, 4)
        self.width = int(self.width)
        self.height = int(self.height)
        if self.width < 1 or self.height < 1:
            raise ValueError(f"camera {self.name!r}: image size must be >= 1, got {self.width}x{self.height}")
        if not (np.isfinite(self.K).all() and np.isfinite(self.viewmat).all()):
            raise ValueError(f"camera {self.name!r}: K and viewmat must be finite")

    # ---- derived quantities -------------------------------------------------
    @property
    def R(self) -> np.ndarray:
        """World-to-camera rotation [3,3]."""
        return self.viewmat[:3, :3]

    @property
    def t(self) -> np.ndarray:
        """World-to-camera translation [3]."""
        return self.viewmat[:3, 3]

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates [3]."""
        return -self.R.T @ self.t

    @property
    def forward(self) -> np.ndarray:
        """Viewing direction (+z of the camera) in world coordinates [3]."""
        return self.R[2].copy()

    @property
    def fov_x(self) -> float:
        """Horizontal field of view in degrees."""
        return math.degrees(2 * math.atan(self.width / (2 * self.K[0, 0])))

    def torch_viewmat(self, device: torch.device | str = "cpu") -> torch.Tensor:
        """viewmat as float32 tensor [4,4]."""
        return torch.as_tensor(self.viewmat, dtype=torch.float32, device=device)

    def torch_K(self, device: torch.device | str = "cpu") -> torch.Tensor:
        """K as float32 tensor [3,3]."""
        return torch.as_tensor(self.K, dtype=torch.float32, device=device)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points [N,3] to pixels [N,2]; also returns depth [N]."""
        pc = points @ self.R.T + self.t
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (pc[:, :2] / z[:, None]) * np.diag(self.K)[:2] + self.K[:2, 2]
        return uv, z

    def scaled(self, width: int, height: int) -> "Camera":
        """Same camera at another resolution (intrinsics scaled per axis)."""
        sx, sy = width / self.width, height / self.height
        K = self.K.copy()
        K[0] *= sx
        K[1] *= sy
        return Camera(K, self.viewmat.copy(), width, height, self.name)

    # ---- IO ------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "width": self.width,
            "height": self.height,
            "K": self.K.tolist(),
            "viewmat": self.viewmat.tolist(),
        }

    @staticmethod
    def from_dict(d: dict) -> "Camera":
        for key in ("width", "height", "K", "viewmat"):
            if key not in d:
                raise KeyError(f"camera entry {d.get('name', '?')!r} lacks key {key!r}")
        return Camera(np.array(d["K"]), np.array(d["viewmat"]), d["width"], d["height"], d.get("name", ""))


def intrinsics_from_fov(fov_x_deg: float, width: int, height: int, fov_y_deg: float | None = None) -> np.ndarray:
    """Intrinsics [3,3] from a horizontal FOV (square pixels unless fov_y is given)."""
    if not 0 < fov_x_deg < 180:
        raise ValueError(f"field of view must be in (0, 180) degrees, got {fov_x_deg}")
    fx = width / (2 * math.tan(math.radians(fov_x_deg) / 2))
    fy = fx if fov_y_deg is None else height / (2 * math.tan(math.radians(fov_y_deg) / 2))
    return np.array([[fx, 0, width / 2], [0, fy, height / 2], [0, 0, 1]], dtype=np.float64)


def look_at(eye: Sequence[float], target: Sequence[float], up: Sequence[float] = (0, 0, 1)) -> np.ndarray:
    """World-to-camera [4,4] for a camera at ``eye`` looking at ``target``.

    OpenCV convention: camera +z towards the target, +y pointing down (opposite ``up``).
    """
    eye = np.asarray(eye, dtype=np.float64)
    fwd = np.asarray(target, dtype=np.float64) - eye
    n = np.linalg.norm(fwd)
    if n < 1e-12:
        raise ValueError("look_at: eye and target coincide")
    fwd /= n
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(fwd, up)
    if np.linalg.norm(right) < 1e-9:  # looking along up: pick any perpendicular
        right = np.cross(fwd, np.array([1.0, 0, 0]) if abs(fwd[0]) < 0.9 else np.array([0, 1.0, 0]))
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    R = np.stack([right, down, fwd])  # rows: camera axes in world coords
    V = np.eye(4)
    V[:3, :3] = R
    V[:3, 3] = -R @ eye
    return V


def save_cameras(path: str | Path, cameras: Sequence[Camera], extra: dict | None = None) -> None:
    """Write cameras as JSON (atomically)."""
    payload = {"convention": "opencv, world-to-camera, pixel centres at +0.5", "cameras": [c.to_dict() for c in cameras]}
    if extra:
        payload.update(extra)
    atomic_write_text(path, json.dumps(payload, indent=1))


def load_cameras(path: str | Path) -> list[Camera]:
    """Read cameras written by :func:`save_cameras`."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"camera file not found: {path}")
    data = json.loads(path.read_text())
    entries = data["cameras"] if isinstance(data, dict) else data
    return [Camera.from_dict(d) for d in entries]


def _is_camera_dict(d: Any) -> bool:
    return isinstance(d, dict) and "K" in d and "viewmat" in d


def load_view_camera(path: str | Path, view_id: str) -> Camera:
    """The camera of view ``view_id`` in a views JSON.

    Accepted layouts: a list of entries, or a dict with the list under ``views`` (or
    ``cameras``); an entry is ``{"id": ..., "camera": {Camera dict}}`` or a Camera dict whose
    ``id``/``name`` is the view id.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"views file not found: {path}")
    data = json.loads(path.read_text())
    entries = data
    if isinstance(data, dict):
        entries = next((data[k] for k in ("views", "cameras") if k in data), None)
        if entries is None:
            raise KeyError(f"{path}: expected a list of views or a dict with 'views' or 'cameras'")
    ids = []
    for e in entries:
        eid = str(e.get("id", e.get("name", "")))
        ids.append(eid)
        if eid == str(view_id):
            cam = e.get("camera", e)
            if not _is_camera_dict(cam):
                raise KeyError(f"{path}: view {view_id!r} has no camera dict (K, viewmat, width, height)")
            cam = dict(cam)
            cam.setdefault("name", eid)
            return Camera.from_dict(cam)
    raise KeyError(f"{path}: no view with id {view_id!r}; views present: {ids}")


def load_camera_json(path: str | Path) -> Camera:
    """A single camera JSON (``Camera.to_dict()``; also accepts ``{"camera": {...}}``)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"camera file not found: {path}")
    d = json.loads(path.read_text())
    if isinstance(d, dict) and "camera" in d and _is_camera_dict(d["camera"]):
        d = d["camera"]
    if not _is_camera_dict(d):
        raise KeyError(f"{path}: not a camera dict (needs K, viewmat, width, height)")
    return Camera.from_dict(d)


def camera_for_size(cam: Camera, h: int, w: int, what: str) -> Camera:
    """``cam`` at an image size of ``w``x``h`` (same aspect ratio required)."""
    if (cam.height, cam.width) == (h, w):
        return cam
    if abs(w / h - cam.width / cam.height) > 0.01:
        raise ValueError(f"{what} is {w}x{h} but camera {cam.name!r} is {cam.width}x{cam.height} "
                         "(different aspect ratio)")
    return cam.scaled(w, h)
