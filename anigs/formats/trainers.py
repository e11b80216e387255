"""The frames other 3DGS trainers write their splats in, read from the files they leave beside them.

Each trainer keeps its own world frame (the importer, :mod:`anigs.static.imported`, maps it onto the
sfm folder's frame):

- **INRIA 3DGS** (``train.py``; also gsplat's and most forks' ``cameras.json``): the COLMAP frame of
  its source project. Beside ``point_cloud/iteration_N/point_cloud.ply`` two folders up lie
  ``cameras.json`` (per photo ``img_name`` without extension, ``position`` = the camera centre,
  ``rotation`` = camera-to-world rotation [3,3] in OpenCV axes, ``fx``, ``fy``, ``width``, ``height``)
  and ``cfg_args`` (the training arguments as a Python ``Namespace(...)`` line: ``source_path``,
  ``white_background``, ``sh_degree``).
- **OpenSplat** (1.1.5, ``autoScaleAndCenterPoses``): centres the COLMAP camera centres on their mean and
  scales them so the largest coordinate is 1 (:func:`opensplat_normalisation`), and writes a
  ``cameras.json`` of the same layout in that frame beside its PLY (rotations in OpenCV axes; with
  ``--keep-crs`` both are written back in the COLMAP frame).
- **nerfstudio** (``ns-export gaussian-splat``): the splat is in the dataparser's frame;
  ``dataparser_transforms.json`` (in the run's folder) holds ``transform`` [3,4] and ``scale``:
  ``p_ns = scale * (T[:, :3] @ p_data + T[:, 3])``, where ``p_data`` is the frame of its
  ``transforms.json``: COLMAP's world with y and z swapped and z negated (``applied_transform``,
  :data:`NERFSTUDIO_APPLIED`) for data that ``ns-process-data`` or its COLMAP dataparser read.
- **gsplat** (``examples/simple_trainer.py`` with ``normalize_world_space``): a similarity computed
  from the COLMAP cameras and points (:func:`gsplat_normalisation`); it writes no file that records it.

This module only reads and computes; the choice of frame and the check against the photos are the
importer's.
"""
from __future__ import annotations

import ast
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: [3,3] nerfstudio's ``applied_transform`` for COLMAP data: (x, y, z) -> (x, z, -y)
NERFSTUDIO_APPLIED = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: camera axes of the OpenGL convention (x right, y up, z back) from OpenCV's (x right, y down, z forward)
OPENGL_AXES = np.diag([1.0, -1.0, -1.0])
#: how many folders above the splat a trainer's files are looked for (INRIA: point_cloud/iteration_N/)
SEARCH_UP = 3
#: OpenSplat 1.1.5 renders onto this fixed colour (model.hpp: nerfstudio's default, not optimised)
OPENSPLAT_BACKGROUND = (0.6130, 0.0101, 0.3984)


@dataclass
class TrainerCameras:
    """Per-photo poses a trainer wrote in its splat's frame (``cameras.json``).

    Attributes:
        path: the file.
        names: photo names as written (INRIA drops the extension).
        centers: [N,3] camera centres in the splat's frame.
        rotations: [N,3,3] camera-to-world rotations in the file's own axis convention.
        sizes: [(width, height)] per photo.
    """

    path: Path
    names: list[str]
    centers: np.ndarray
    rotations: np.ndarray
    sizes: list[tuple[int, int]] = field(default_factory=list)


@dataclass
class TrainerFiles:
    """What a trainer left beside a splat (each None when absent)."""

    cameras: TrainerCameras | None = None
    cfg_args: dict | None = None  # INRIA's training arguments
    cfg_args_path: Path | None = None
    dataparser: np.ndarray | None = None  # [4,4] nerfstudio: its frame from the data frame
    dataparser_path: Path | None = None

    def found(self) -> list[str]:
        """The files found, as paths (for the log and metrics.json)."""
        return [str(p) for p in (self.cameras.path if self.cameras else None, self.cfg_args_path,
                                 self.dataparser_path) if p is not None]

    def trainer(self) -> str | None:
        """Which trainer the files look like: ``inria`` (its ``cfg_args``), ``opensplat`` (a ``cameras.json``
        whose photo names keep their extension, no ``cfg_args``), ``nerfstudio``; None when unknown."""
        if self.cfg_args is not None:
            return "inria"
        if self.dataparser is not None:
            return "nerfstudio"
        if self.cameras is not None and all(Path(n).suffix for n in self.cameras.names):
            return "opensplat"
        return None

    def background(self) -> tuple[tuple[float, float, float], str] | None:
        """The background the trainer rendered onto and why, when its files tell (INRIA's
        ``white_background``; OpenSplat's fixed colour)."""
        if self.cfg_args is not None and "white_background" in self.cfg_args:
            white = bool(self.cfg_args["white_background"])
            return ((1.0, 1.0, 1.0) if white else (0.0, 0.0, 0.0)), f"{self.cfg_args_path} white_background"
        if self.trainer() == "opensplat":
            return OPENSPLAT_BACKGROUND, f"OpenSplat's fixed background ({self.cameras.path.name} names keep extensions)"
        return None


def _near(splat: Path, name: str) -> Path | None:
    """The first file ``name`` in the splat's folder or up to :data:`SEARCH_UP` folders above it."""
    d = splat.resolve().parent
    for _ in range(SEARCH_UP + 1):
        if (d / name).is_file():
            return d / name
        if d.parent == d:
            break
        d = d.parent
    return None


def trainer_files(splat: str | Path) -> TrainerFiles:
    """The trainer files beside ``splat`` (:class:`TrainerFiles`); malformed files are errors naming them."""
    splat = Path(splat)
    out = TrainerFiles()
    p = _near(splat, "cameras.json")
    if p is not None:
        out.cameras = read_trainer_cameras(p)
    p = _near(splat, "cfg_args")
    if p is not None:
        out.cfg_args, out.cfg_args_path = read_cfg_args(p), p
    p = _near(splat, "dataparser_transforms.json")
    if p is not None:
        out.dataparser, out.dataparser_path = read_dataparser_transforms(p), p
    return out


def read_trainer_cameras(path: str | Path) -> TrainerCameras:
    """An INRIA-layout ``cameras.json`` (INRIA 3DGS, OpenSplat, gsplat's exports): a list of
    ``{img_name, position [3], rotation [3][3], width, height, ...}``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ValueError(f"{path}: not a readable JSON file ({err})") from None
    if isinstance(data, dict) and "cameras" in data:
        raise ValueError(f"{path}: an anigs cameras file, not a trainer's (INRIA layout: a list of "
                         "{img_name, position, rotation})")
    if not isinstance(data, list) or not data:
        raise ValueError(f"{path}: expected a non-empty list of cameras (INRIA layout)")
    names, centers, rots, sizes = [], [], [], []
    for i, e in enumerate(data):
        try:
            names.append(str(e["img_name"]))
            centers.append(np.asarray(e["position"], float).reshape(3))
            rots.append(np.asarray(e["rotation"], float).reshape(3, 3))
            sizes.append((int(e.get("width", 0)), int(e.get("height", 0))))
        except (KeyError, TypeError, ValueError) as err:
            raise ValueError(f"{path}: camera {i} lacks img_name/position/rotation ({err})") from None
    c, r = np.stack(centers), np.stack(rots)
    if not (np.isfinite(c).all() and np.isfinite(r).all()):
        raise ValueError(f"{path}: non-finite camera positions or rotations")
    return TrainerCameras(path, names, c, r, sizes)


_CFG = re.compile(r"^\s*Namespace\((.*)\)\s*$", re.S)


def read_cfg_args(path: str | Path) -> dict:
    """INRIA's ``cfg_args``: ``Namespace(key=value, ...)`` as a dict of the literal values."""
    path = Path(path)
    m = _CFG.match(path.read_text())
    if not m:
        raise ValueError(f"{path}: not an INRIA cfg_args file (expected 'Namespace(...)')")
    try:
        call = ast.parse(f"f({m.group(1)})", mode="eval").body
        return {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords if kw.arg}
    except (SyntaxError, ValueError) as err:
        raise ValueError(f"{path}: unreadable cfg_args ({err})") from None


def read_dataparser_transforms(path: str | Path) -> np.ndarray:
    """nerfstudio's ``dataparser_transforms.json`` as a [4,4] matrix: its frame from the data frame."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
        T = np.asarray(d["transform"], float).reshape(3, 4)
        s = float(d["scale"])
    except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
        raise ValueError(f"{path}: not a nerfstudio dataparser_transforms.json (transform [3,4], scale): {err}") from None
    if not (np.isfinite(T).all() and s > 0):
        raise ValueError(f"{path}: non-finite transform or scale {s} <= 0")
    M = np.eye(4)
    M[:3, :] = s * T
    return M


def opensplat_normalisation(centers: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre [3], factor): OpenSplat's frame of COLMAP points ``x`` is ``(x - centre) * factor``, from the
    COLMAP camera centres [N,3] (their mean, and one over the largest absolute coordinate about it)."""
    c = np.asarray(centers, float)
    centre = c.mean(0)
    return centre, 1.0 / float(np.abs(c - centre).max())


def gsplat_normalisation(c2w: np.ndarray, points: np.ndarray) -> np.ndarray:
    """[4,4] the similarity gsplat's COLMAP parser applies with ``normalize_world_space`` (its
    ``similarity_from_cameras`` with ``center_method="focus"``, ``align_principal_axes``, and the flip
    of z when the points' median height lies above their mean), from the COLMAP camera-to-world
    poses ``c2w`` [N,4,4] (OpenCV axes) and points [P,3]. The principal axes' signs follow numpy's
    ``eigh``, as in gsplat; the importer also tries the other signs."""
    c2w = np.asarray(c2w, float)
    t, R = c2w[:, :3, 3], c2w[:, :3, :3]
    world_up = (R @ np.array([0.0, -1.0, 0.0])).mean(0)
    world_up /= np.linalg.norm(world_up)
    cam_up = np.array([0.0, -1.0, 0.0])
    cosine = float(cam_up @ world_up)
    cross = np.cross(world_up, cam_up)
    skew = np.array([[0.0, -cross[2], cross[1]], [cross[2], 0.0, -cross[0]], [-cross[1], cross[0], 0.0]])
    align = np.eye(3) + skew + skew @ skew / (1 + cosine) if cosine > -1 else np.diag([-1.0, 1.0, 1.0])
    fwd = (align @ R)[:, :, 2]
    t = t @ align.T
    nearest = t + ((fwd * -t).sum(-1))[:, None] * fwd
    shift = -np.median(nearest, axis=0)
    T1 = np.eye(4)
    T1[:3, :3], T1[:3, 3] = align, shift
    T1[:3, :] *= 1.0 / np.median(np.linalg.norm(t + shift, axis=-1))
    pts = np.asarray(points, float) @ T1[:3, :3].T + T1[:3, 3]
    centroid = np.median(pts, axis=0)
    vals, vecs = np.linalg.eigh(np.cov(pts - centroid, rowvar=False))
    vecs = vecs[:, vals.argsort()[::-1]]
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] *= -1
    T2 = np.eye(4)
    T2[:3, :3], T2[:3, 3] = vecs.T, -vecs.T @ centroid
    M = T2 @ T1
    pts = pts @ T2[:3, :3].T + T2[:3, 3]
    if np.median(pts[:, 2]) > np.mean(pts[:, 2]):
        M = np.diag([1.0, -1.0, -1.0, 1.0]) @ M
    return M
