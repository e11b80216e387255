"""A COLMAP project the tests write by hand: photos rendered from known cameras, and a text model of
those cameras in a frame of the user's (rotated, shifted and scaled away from anigs's z-up frame), with
the scene's points observed in every photo that sees them. pycolmap turns it into the binary form."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.sfm.align import Similarity

from tests.sfm._captures import W, H, render

#: the user's frame: x_user = USER_FRAME.apply(x_scene) (a COLMAP project's world is arbitrary)
USER_FRAME = Similarity(2.5, Rotation.from_euler("xyz", [100, -20, 35], degrees=True).as_matrix(),
                        np.array([4.0, -7.0, 1.5]))


def write_text_model(model: Path, cams: list[Camera], points: np.ndarray, colours: np.ndarray,
                     camera_model: str = "PINHOLE", params: tuple[float, ...] | None = None) -> dict[str, int]:
    """``cameras.txt``, ``images.txt``, ``points3D.txt`` of ``cams`` (one camera each) and ``points`` [P,3]
    (colours [P,3] in [0,1]) observed by every camera they project into; returns image name -> id."""
    model.mkdir(parents=True, exist_ok=True)
    cam_lines, img_lines, tracks = [], [], {j: [] for j in range(len(points))}
    ids = {}
    for i, c in enumerate(cams, 1):
        fx, fy, cx, cy = c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2]
        p = params if params is not None else (fx, fy, cx, cy)
        cam_lines.append(f"{i} {camera_model} {c.width} {c.height} " + " ".join(f"{v:.17g}" for v in p))
        q = Rotation.from_matrix(c.R).as_quat()  # x, y, z, w
        t = c.t
        img_lines.append(f"{i} {q[3]:.17g} {q[0]:.17g} {q[1]:.17g} {q[2]:.17g} {t[0]:.17g} {t[1]:.17g} {t[2]:.17g} "
                         f"{i} {c.name}")
        uv, depth = c.project(points)
        seen = np.flatnonzero((depth > 0.1) & (uv[:, 0] >= 0) & (uv[:, 0] < c.width) & (uv[:, 1] >= 0)
                              & (uv[:, 1] < c.height))
        obs = []
        for k, j in enumerate(seen):
            obs.append(f"{uv[j, 0]:.6f} {uv[j, 1]:.6f} {j + 1}")
            tracks[j].append((i, k))
        img_lines.append(" ".join(obs))
        ids[c.name] = i
    pts_lines = []
    for j, (x, col) in enumerate(zip(points, colours)):
        if len(tracks[j]) < 2:
            continue
        rgb = " ".join(str(int(round(v * 255))) for v in col)
        track = " ".join(f"{i} {k}" for i, k in tracks[j])
        pts_lines.append(f"{j + 1} {x[0]:.17g} {x[1]:.17g} {x[2]:.17g} {rgb} 0.25 {track}")
    (model / "cameras.txt").write_text("# written by tests/sfm/_project.py\n" + "\n".join(cam_lines) + "\n")
    (model / "images.txt").write_text("\n".join(img_lines) + "\n")
    (model / "points3D.txt").write_text("\n".join(pts_lines) + "\n")
    return ids


def colmap_project(root: Path, cams: list[Camera], scene: Gaussians, num_points: int = 600, seed: int = 0
                   ) -> dict[str, Path]:
    """A COLMAP project under ``root``: ``images/`` rendered from ``cams`` (anigs's frame), ``sparse/0``
    (text) and ``sparse_bin/0`` (binary) with the cameras in :data:`USER_FRAME`."""
    import pycolmap

    images, _ = render(root, cams, scene)
    rng = np.random.default_rng(seed)
    pick = rng.choice(scene.num, size=min(num_points, scene.num), replace=False)
    pts = scene.means[pick].double().numpy()
    cols = np.clip(scene.sh[pick, 0].double().numpy() * 0.28209479177387814 + 0.5, 0, 1)
    user_cams = [USER_FRAME.apply_camera(c) for c in cams]
    write_text_model(root / "sparse" / "0", user_cams, USER_FRAME.apply(pts), cols)
    binary = root / "sparse_bin" / "0"
    binary.mkdir(parents=True)
    pycolmap.Reconstruction(str(root / "sparse" / "0")).write(str(binary))
    return {"images": images, "text": root / "sparse" / "0", "binary": binary}


__all__ = ["H", "USER_FRAME", "W", "colmap_project", "write_text_model"]
