"""Export the animated scene for viewers.

* a per-frame PLY sequence in the standard 3DGS layout (any viewer plays it);
* one compact PLY: the standard 3DGS properties of the canonical scene plus per-Gaussian
  ``dyn`` (0/1) and DCT coefficients ``dct_pos_{x,y,z}_{k}`` / ``dct_rot_{x,y,z}_{k}``
  (k = 1..K; zero for static Gaussians), with a JSON sidecar giving the formula. Viewers that
  do not know the extra properties show the static scene.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch

from anigs.animate.deform import DCTDeformation
from anigs.gaussians import Gaussians, load_ply, ply_property_names
from anigs.io import atomic_path

AXES = ("x", "y", "z")

FORMULA = {
    "basis": "b_k(t) = sqrt(2/(K+1)) * cos(pi/(2T) * (2t+1) * k), k = 1..K, t in [0, T-1] (fractional allowed)",
    "position": "mu(t) = mu_0 + sum_k dct_pos_{axis}_{k} * b_k(t)   (world units)",
    "rotation": "q(t) = exp(w(t)) (x) q_0 (Hamilton product, w,x,y,z), w(t) = sum_k dct_rot_{axis}_{k} * b_k(t) "
                "(rotation vector, radians; exp maps it to the unit quaternion (cos|w|/2, sin|w|/2 w/|w|))",
    "static": "Gaussians with dyn = 0 never move",
    "looping": "the DCT motion is even-symmetric in time: loop by playing 0..T-1 forward then backward",
}


def extra_property_names(num_bases: int, rotation: bool) -> list[str]:
    names = ["dyn"] + [f"dct_pos_{a}_{k}" for a in AXES for k in range(1, num_bases + 1)]
    if rotation:
        names += [f"dct_rot_{a}_{k}" for a in AXES for k in range(1, num_bases + 1)]
    return names


def save_animated_ply(path: str | Path, canonical: Gaussians, deformation: DCTDeformation) -> list[str]:
    """Write the compact animated PLY; returns the extra property names."""
    g = canonical.detach().to("cpu")
    n, c, K = g.num, g.sh.shape[1], deformation.num_bases
    names = ply_property_names(g.sh_degree)
    std = np.concatenate([
        g.means.numpy(), np.zeros((n, 3), np.float32), g.sh[:, 0].numpy(),
        g.sh[:, 1:].transpose(1, 2).reshape(n, 3 * (c - 1)).numpy(),
        g.opacity_logits[:, None].numpy(), g.log_scales.numpy(), g.quats.numpy()], axis=1)
    rotation = deformation.rot_coeffs is not None
    extra_names = extra_property_names(K, rotation)
    extra = np.zeros((n, len(extra_names)), np.float32)
    idx = deformation.dynamic_index.cpu().numpy()
    extra[idx, 0] = 1
    pos = deformation.pos_coeffs.detach().cpu().numpy()  # [D,3,K]
    extra[idx, 1:1 + 3 * K] = pos.reshape(len(idx), 3 * K)
    if rotation:
        rot = deformation.rot_coeffs.detach().cpu().numpy()
        extra[idx, 1 + 3 * K:] = rot.reshape(len(idx), 3 * K)
    data = np.concatenate([std, extra], axis=1).astype("<f4")
    all_names = names + extra_names
    header = "ply\nformat binary_little_endian 1.0\ncomment anigs animated 3DGS: see the .json sidecar\n"
    header += f"element vertex {n}\n" + "".join(f"property float {p}\n" for p in all_names) + "end_header\n"
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(np.ascontiguousarray(data).tobytes())
    return extra_names


def load_animated_ply(path: str | Path, num_frames: int) -> tuple[Gaussians, DCTDeformation]:
    """Read a compact animated PLY back (the sidecar gives ``num_frames``)."""
    g = load_ply(path)
    with open(path, "rb") as fh:
        header = []
        while True:
            line = fh.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        props = [ln.split()[-1] for ln in header if ln.startswith("property")]
        raw = np.frombuffer(fh.read(), dtype="<f4").reshape(g.num, len(props))
    col = {p: i for i, p in enumerate(props)}
    if "dyn" not in col:
        raise ValueError(f"{path}: no 'dyn' property: not an anigs animated PLY")
    K = sum(1 for p in props if p.startswith("dct_pos_x_"))
    rotation = "dct_rot_x_1" in col
    idx = np.nonzero(raw[:, col["dyn"]] > 0.5)[0]
    d = DCTDeformation(torch.from_numpy(idx), num_frames, K, rotation=rotation, num_gaussians=g.num)
    take = lambda kind: torch.from_numpy(np.stack(
        [raw[idx][:, [col[f"dct_{kind}_{a}_{k}"] for k in range(1, K + 1)]] for a in AXES], axis=1).copy())
    with torch.no_grad():
        d.pos_coeffs.copy_(take("pos"))
        if rotation:
            d.rot_coeffs.copy_(take("rot"))
    return g, d


def sidecar(deformation: DCTDeformation, fps: float, ply_name: str, extra_names: list[str]) -> dict:
    """JSON sidecar describing the compact PLY."""
    return {
        "format": "anigs-animated-3dgs/1",
        "ply": ply_name,
        "num_frames": deformation.num_frames,
        "num_bases": deformation.num_bases,
        "fps": fps,
        "num_dynamic": deformation.num_dynamic,
        "basis_scale": math.sqrt(2.0 / (deformation.num_bases + 1)) if deformation.num_bases else 0.0,
        "rotation": deformation.rot_coeffs is not None,
        "extra_properties": extra_names,
        "formula": FORMULA,
        "note": "max_offset/max_angle soft limits of training are baked out: coefficients are applied as written "
                "only when the model had no limits; otherwise use the frame sequence for exact playback",
        "limits": {"max_offset": deformation.max_offset is not None, "max_angle": deformation.max_angle is not None},
    }
