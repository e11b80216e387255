"""glTF binary (``.glb``) with the ``KHR_gaussian_splatting`` extension (status "Release
Candidate" in KhronosGroup/glTF, checked 2026-07-17 at 77b44be; static splats only).

One mesh of one ``POINTS`` primitive whose attributes are, per Gaussian: ``POSITION`` (float VEC3),
``COLOR_0`` (unsigned byte RGBA, the fallback for point-cloud viewers), and the extension's
``KHR_gaussian_splatting:ROTATION`` (unit quaternion x, y, z, w), ``:SCALE`` (linear), ``:OPACITY``
(after the sigmoid), ``:SH_DEGREE_0_COEF_0`` and ``:SH_DEGREE_l_COEF_n`` (RGB per coefficient, m from
-l to l). The positions stay in anigs's +z-up frame (they equal ``canonical.ply``'s); the node carries
the -90 degree rotation about x that stands the scene upright in glTF's +y-up frame, which a viewer
applies to the positions, the covariances and (per the extension) the SH coefficients.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import torch

from anigs.formats.orientation import Y_UP_QUAT_XYZW
from anigs.gaussians import SH_C0, Gaussians
from anigs.io import atomic_path

EXT = "KHR_gaussian_splatting"
FLOAT, UNSIGNED_BYTE, ARRAY_BUFFER = 5126, 5121, 34962
_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4"}


def glb_attributes(g: Gaussians) -> dict[str, np.ndarray]:
    """The primitive's attributes of ``g``: semantic -> [N, 1|3|4] array (float32, COLOR_0 uint8)."""
    g = g.detach().to("cpu")
    q = g.quats.double()
    norm = q.norm(dim=1, keepdim=True)
    q = torch.where(norm > 0, q / norm.clamp_min(1e-30), torch.tensor([1.0, 0, 0, 0], dtype=q.dtype))
    rgb = (g.sh[:, 0].double() * SH_C0 + 0.5).clamp(0, 1)
    alpha = torch.sigmoid(g.opacity_logits.double())
    out = {
        "POSITION": g.means.numpy(),
        "COLOR_0": np.round(torch.cat([rgb, alpha[:, None]], 1).numpy() * 255).astype(np.uint8),
        f"{EXT}:ROTATION": q[:, [1, 2, 3, 0]].numpy(),
        f"{EXT}:SCALE": g.log_scales.double().exp().numpy(),
        f"{EXT}:OPACITY": alpha[:, None].numpy(),
        f"{EXT}:SH_DEGREE_0_COEF_0": g.sh[:, 0].numpy(),
    }
    for d in range(1, g.sh_degree + 1):
        for c in range(2 * d + 1):
            out[f"{EXT}:SH_DEGREE_{d}_COEF_{c}"] = g.sh[:, d * d + c].numpy()
    return {k: np.ascontiguousarray(v if v.dtype == np.uint8 else v.astype(np.float32)) for k, v in out.items()}


def glb_document(g: Gaussians, generator: str = "anigs") -> tuple[dict, bytes]:
    """The glTF JSON and the binary buffer of ``g``."""
    attrs = glb_attributes(g)
    views, accessors, semantics, chunks, offset = [], [], {}, [], 0
    for i, (name, arr) in enumerate(attrs.items()):
        data = arr.tobytes()
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(data), "target": ARRAY_BUFFER})
        acc = {"bufferView": i, "componentType": UNSIGNED_BYTE if arr.dtype == np.uint8 else FLOAT,
               "count": int(arr.shape[0]), "type": _TYPES[arr.shape[1]]}
        if arr.dtype == np.uint8:
            acc["normalized"] = True
        if name == "POSITION":
            acc["min"] = arr.min(0).astype(float).tolist() if len(arr) else [0.0] * 3
            acc["max"] = arr.max(0).astype(float).tolist() if len(arr) else [0.0] * 3
        accessors.append(acc)
        semantics[name] = i
        pad = (-len(data)) % 4
        chunks.append(data + b"\0" * pad)
        offset += len(data) + pad
    binary = b"".join(chunks)
    doc = {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": [EXT],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        # anigs's +z up -> glTF's +y up (the positions keep canonical.ply's values)
        "nodes": [{"name": "canonical", "mesh": 0, "rotation": list(Y_UP_QUAT_XYZW)}],
        "meshes": [{"name": "canonical", "primitives": [{
            "attributes": semantics, "mode": 0,
            "extensions": {EXT: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display",
                                 "projection": "perspective", "sortingMethod": "cameraDistance"}}}]}],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    return doc, binary


def save_glb(path: str | Path, g: Gaussians, generator: str = "anigs") -> None:
    """Write ``g`` as a ``.glb`` with ``KHR_gaussian_splatting``."""
    doc, binary = glb_document(g, generator)
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * ((-len(js)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(struct.pack("<4sII", b"glTF", 2, total))
            fh.write(struct.pack("<I4s", len(js), b"JSON") + js)
            fh.write(struct.pack("<I4s", len(binary), b"BIN\0") + binary)
