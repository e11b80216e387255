"""glTF binary (``.glb``) with the ``KHR_gaussian_splatting`` extension (status "Release
Candidate" in KhronosGroup/glTF, checked 2026-07-17 at 77b44be; static splats only).

One mesh of one ``POINTS`` primitive whose attributes are, per Gaussian: ``POSITION`` (float VEC3),
``COLOR_0`` (unsigned byte RGBA, the fallback for point-cloud viewers), and the extension's
``KHR_gaussian_splatting:ROTATION`` (unit quaternion x, y, z, w), ``:SCALE`` (linear), ``:OPACITY``
(after the sigmoid), ``:SH_DEGREE_0_COEF_0`` and ``:SH_DEGREE_l_COEF_n`` (RGB per coefficient, m from
-l to l). The positions stay in anigs's +z-up frame (they equal ``canonical.ply``'s); the node carries
the -90 degree rotation about x that stands the scene upright in glTF's +y-up frame, which a viewer
applies to the positions, the covariances and (per the extension) the SH coefficients.

:func:`load_glb` reads such files back (anigs's and other tools'): ``apply_nodes=False`` gives the
attribute values as stored (for an anigs file: anigs's +z-up frame, ``canonical.ply``'s values);
``apply_nodes=True`` gives glTF's world (+y up), each instance moved by its node's global transform
(a similarity: uniform scale, rotation, translation; SH rotated too).
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import torch

from anigs.formats.orientation import Y_UP_QUAT_XYZW
from anigs.gaussians import SH_C0, Gaussians
from anigs.geometry.quaternion import quat_to_rotmat
from anigs.geometry.transform import transform_gaussians
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
    with atomic_path(path) as tmp:
        tmp.write_bytes(glb_bytes(doc, binary))


def glb_bytes(doc: dict, binary: bytes) -> bytes:
    """A ``.glb`` file of the glTF JSON ``doc`` and its binary buffer (chunks padded to 4 bytes)."""
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * ((-len(js)) % 4)
    binary = binary + b"\0" * ((-len(binary)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(js), b"JSON") + js
            + struct.pack("<I4s", len(binary), b"BIN\0") + binary)


# ---------------------------------------------------------------------------
# reader
_COMPONENTS = {5120: ("i1", 127), 5121: ("u1", 255), 5122: ("<i2", 32767), 5123: ("<u2", 65535),
               5125: ("<u4", 0), 5126: ("<f4", 0)}  # dtype, normalisation divisor
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_COMPRESSIONS = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression")
_READ_REQUIRED = (EXT, "KHR_mesh_quantization")  # required extensions this reader honours
_OPACITY_EPS = 2.0 ** -24  # opacity 0 or 1 -> a finite logit


def read_glb(path: str | Path) -> tuple[dict, bytes]:
    """The glTF JSON and the ``BIN`` chunk (empty if none) of the ``.glb`` at ``path``."""
    raw = Path(path).read_bytes()
    if len(raw) < 20 or raw[:4] != b"glTF":
        raise ValueError(f"{path}: not a glb file (no 'glTF' magic)")
    version, total = struct.unpack_from("<II", raw, 4)
    if version != 2 or total > len(raw):
        raise ValueError(f"{path}: glb version {version} with {total} bytes (file {len(raw)}); expected version 2")
    doc, binary, off = None, b"", 12
    while off + 8 <= total:
        length, kind = struct.unpack_from("<I4s", raw, off)
        if off + 8 + length > total:
            raise ValueError(f"{path}: truncated glb chunk {kind!r}")
        data = raw[off + 8:off + 8 + length]
        if doc is None:
            if kind != b"JSON":
                raise ValueError(f"{path}: the first glb chunk is {kind!r}, not JSON")
            doc = json.loads(data)
        elif kind == b"BIN\0" and not binary:
            binary = data
        off += 8 + length + (-length) % 4
    if doc is None:
        raise ValueError(f"{path}: glb without a JSON chunk")
    return doc, binary


def _accessor(doc: dict, binary: bytes, index: int, what: str) -> np.ndarray:
    """Accessor ``index`` as float64 [count, width] (normalized integers mapped to [0,1] / [-1,1])."""
    accessors = doc.get("accessors", [])
    if not 0 <= index < len(accessors):
        raise ValueError(f"{what}: accessor {index} does not exist")
    acc = accessors[index]
    if "sparse" in acc:
        raise ValueError(f"{what}: sparse accessors are not supported")
    if acc.get("componentType") not in _COMPONENTS or acc.get("type") not in _WIDTHS:
        raise ValueError(f"{what}: accessor of componentType {acc.get('componentType')} and type "
                         f"{acc.get('type')} is not supported (expected SCALAR or VEC2-4)")
    code, divisor = _COMPONENTS[acc["componentType"]]
    dtype, width, count = np.dtype(code), _WIDTHS[acc["type"]], int(acc["count"])
    if "bufferView" not in acc or count == 0:
        return np.zeros((count, width))
    views = doc.get("bufferViews", [])
    if not 0 <= acc["bufferView"] < len(views):
        raise ValueError(f"{what}: buffer view {acc['bufferView']} does not exist")
    view = views[acc["bufferView"]]
    for ext in view.get("extensions", {}):
        if ext in _COMPRESSIONS:
            raise ValueError(f"{what}: compressed buffer view ({ext}) is not supported")
    if view.get("buffer", 0) != 0 or "uri" in doc["buffers"][view.get("buffer", 0)]:
        raise ValueError(f"{what}: data outside the glb's BIN chunk (buffer {view.get('buffer')}) is not supported")
    elem = dtype.itemsize * width
    stride = view.get("byteStride", elem)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    end = start + stride * (count - 1) + elem
    if end > view.get("byteOffset", 0) + view["byteLength"] or end > len(binary):
        raise ValueError(f"{what}: accessor {index} reaches byte {end}, past its buffer view or the BIN chunk")
    out = np.ndarray((count, width), dtype, buffer=binary, offset=start, strides=(stride, dtype.itemsize))
    out = out.astype(np.float64)
    if acc.get("normalized") and divisor:
        out = np.maximum(out / divisor, -1.0)
    return out


def _srgb_encode(linear: np.ndarray) -> np.ndarray:
    """sRGB transfer function of linear values in [0, 1]."""
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def _sh_coefficients(doc: dict, binary: bytes, prim: dict, what: str) -> np.ndarray:
    """[N,C,3] SH of a splat primitive: ``SH_DEGREE_l_COEF_n`` or, without degree 0, ``COLOR_0``
    (linear per glTF; sRGB-encoded first for the ``srgb_rec709_display`` colour space)."""
    attrs = prim["attributes"]
    get = lambda name: _accessor(doc, binary, attrs[name], f"{what} {name}")
    if f"{EXT}:SH_DEGREE_0_COEF_0" in attrs:
        coeffs = [get(f"{EXT}:SH_DEGREE_0_COEF_0")]
    elif "COLOR_0" in attrs:
        rgb = get("COLOR_0")[:, :3]
        if prim["extensions"][EXT].get("colorSpace", "srgb_rec709_display") == "srgb_rec709_display":
            rgb = _srgb_encode(rgb)
        coeffs = [(rgb - 0.5) / SH_C0]
    else:
        raise ValueError(f"{what}: missing attributes: {EXT}:SH_DEGREE_0_COEF_0 (or COLOR_0)")
    full = True
    for d in range(1, 4):
        names = [f"{EXT}:SH_DEGREE_{d}_COEF_{c}" for c in range(2 * d + 1)]
        have = [n in attrs for n in names]
        if any(have) and not (full and all(have)):
            lacking = [n for n, h in zip(names, have) if not h] or f"a degree below {d}"
            raise ValueError(f"{what}: SH degree {d} is partly defined or lacks a lower degree (missing {lacking})")
        full = full and all(have)
        if full:
            coeffs += [get(n) for n in names]
    if any(c.shape[1] != 3 for c in coeffs):
        raise ValueError(f"{what}: SH attributes must be VEC3")
    return np.stack(coeffs, 1)


def _primitive_gaussians(doc: dict, binary: bytes, prim: dict, what: str) -> Gaussians:
    """The Gaussians of one ``KHR_gaussian_splatting`` primitive, as stored (no node transform)."""
    attrs = prim.get("attributes", {})
    need = {"POSITION": 3, f"{EXT}:ROTATION": 4, f"{EXT}:SCALE": 3, f"{EXT}:OPACITY": 1}
    missing = [k for k in need if k not in attrs]
    if missing:
        raise ValueError(f"{what}: missing attributes {missing}")
    a = {k: _accessor(doc, binary, attrs[k], f"{what} {k}") for k in need}
    sh = _sh_coefficients(doc, binary, prim, what)
    n = len(a["POSITION"])
    bad = {k: v.shape for k, v in a.items() if v.shape != (n, need[k])}
    if bad or len(sh) != n:
        raise ValueError(f"{what}: attribute shapes {bad or {'SH': sh.shape}} do not match {n} positions")
    scale = a[f"{EXT}:SCALE"]
    if (scale < 0).any():
        raise ValueError(f"{what}: negative {EXT}:SCALE values")
    alpha = np.clip(a[f"{EXT}:OPACITY"][:, 0], _OPACITY_EPS, 1 - _OPACITY_EPS)
    f32 = lambda x: torch.from_numpy(np.ascontiguousarray(x, np.float32))
    return Gaussians(f32(a["POSITION"]), f32(a[f"{EXT}:ROTATION"][:, [3, 0, 1, 2]]),
                     f32(np.log(np.maximum(scale, np.finfo(np.float32).tiny))),
                     f32(np.log(alpha / (1 - alpha))), f32(sh))


def _node_matrix(node: dict) -> np.ndarray:
    """The node's local transform [4,4] (``matrix``, column-major, or translation * rotation * scale)."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    M = np.eye(4)
    M[:3, :3] = quat_to_rotmat(torch.tensor([[w, x, y, z]], dtype=torch.float64))[0].numpy()
    M[:3, :3] *= np.asarray(node.get("scale", (1.0, 1.0, 1.0)), np.float64)[None, :]
    M[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return M


def _mesh_instances(doc: dict) -> list[tuple[int, int, np.ndarray]]:
    """(node, mesh, global transform [4,4]) of every node with a mesh in the default scene (all root
    nodes when the file has no scenes)."""
    nodes = doc.get("nodes", [])
    if doc.get("scenes"):
        roots = doc["scenes"][doc.get("scene", 0)].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out, stack = [], [(r, np.eye(4), ()) for r in reversed(roots)]
    while stack:
        i, parent, path = stack.pop()
        if i in path:
            raise ValueError(f"node {i} is its own ancestor")
        M = parent @ _node_matrix(nodes[i])
        if "mesh" in nodes[i]:
            out.append((i, nodes[i]["mesh"], M))
        stack += [(c, M, path + (i,)) for c in reversed(nodes[i].get("children", []))]
    return out


def node_similarity(M: np.ndarray, what: str = "node") -> tuple[float, np.ndarray, np.ndarray]:
    """(scale, R [3,3], t [3]) of a global node transform ``M`` [4,4] = [s R | t]; ValueError for a
    non-uniform or negative scale, a shear or a projective row."""
    A = M[:3, :3]
    cols = np.linalg.norm(A, axis=0)
    if not np.allclose(M[3], [0, 0, 0, 1]) or not (cols > 0).all() or cols.max() - cols.min() > 1e-5 * cols.max():
        raise ValueError(f"{what}: transform is not a similarity (column lengths {cols.round(6).tolist()}); "
                         "non-uniform node scales are not supported: read with apply_nodes=False")
    s = float(cols.mean())
    R = A / s
    if np.linalg.det(R) < 0 or np.abs(R.T @ R - np.eye(3)).max() > 1e-5:
        raise ValueError(f"{what}: transform has a negative scale (mirror) or a shear; not a similarity")
    U, _, Vt = np.linalg.svd(R)
    return s, U @ Vt, M[:3, 3].copy()


def _check_extensions(doc: dict, path: Path) -> None:
    """Refuse what this reader cannot decode, naming the extension."""
    other = [e for e in doc.get("extensionsRequired", []) if e not in _READ_REQUIRED]
    if other:
        raise ValueError(f"{path}: requires glTF extensions {other}, which this reader does not support "
                         f"(it reads {list(_READ_REQUIRED)}; Draco and meshopt compression are refused)")
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            exts = prim.get("extensions", {})
            named = [e for e in exts if e in _COMPRESSIONS]
            named += [e for e in exts.get(EXT, {}).get("extensions", {}) if "compression" in e]
            if named:
                raise ValueError(f"{path}: compressed primitive ({', '.join(named)}) is not supported")


def load_glb(path: str | Path, apply_nodes: bool = False) -> Gaussians:
    """The Gaussians of every ``KHR_gaussian_splatting`` primitive of the ``.glb`` at ``path``.

    ``apply_nodes=False``: the attribute values as stored, each primitive once (anigs's files: its
    +z-up frame, as written). ``apply_nodes=True``: glTF's world frame (+y up), one copy per node
    instancing a splat mesh in the default scene, moved by the node's global transform
    (:func:`node_similarity`, :func:`anigs.geometry.transform.transform_gaussians`).
    Normalized integer accessors, ``byteStride`` and accessor offsets are read; sparse accessors,
    Draco and meshopt compression are refused (ValueError), as are missing attributes.
    """
    path = Path(path)
    doc, binary = read_glb(path)
    _check_extensions(doc, path)
    splat = {m: [(j, p) for j, p in enumerate(mesh.get("primitives", [])) if EXT in p.get("extensions", {})]
             for m, mesh in enumerate(doc.get("meshes", []))}
    if not any(splat.values()):
        raise ValueError(f"{path}: no mesh primitive with the {EXT} extension")
    read = lambda m, j, p: _primitive_gaussians(doc, binary, p, f"{path}: mesh {m} primitive {j}")
    if not apply_nodes:
        parts = [read(m, j, p) for m, prims in splat.items() for j, p in prims]
    else:
        parts = []
        for node, m, M in _mesh_instances(doc):
            for j, p in splat.get(m, []):
                s, R, t = node_similarity(M, f"{path}: node {node}")
                parts.append(transform_gaussians(read(m, j, p), s, R, t))
        if not parts:
            raise ValueError(f"{path}: no node of the scene instances a {EXT} mesh (read with apply_nodes=False)")
    return parts[0] if len(parts) == 1 else Gaussians.concat(parts)
