"""The static scene for other tools: ``canonical.spz`` and ``canonical.glb`` (KHR_gaussian_splatting),
read back by real readers (splat-transform, gsply, pygltflib, Khronos's glTF validator); and the
README's orientation table checked against :mod:`anigs.formats.orientation` (issue 37)."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import torch

from anigs.formats.gltf import EXT, save_glb
from anigs.formats.orientation import SUPERSPLAT, Y_UP, Y_UP_QUAT_XYZW
from anigs.formats.spz import load_spz, save_spz
from anigs.gaussians import Gaussians, load_ply
from tests._node import needs_node, node_script, splat_transform

ROOT = Path(__file__).resolve().parents[2]


def _scene(n=700, deg=3, seed=0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    sh = torch.randn(n, (deg + 1) ** 2, 3, generator=g) * 0.2
    return Gaussians(torch.rand(n, 3, generator=g) * 6 - 3, torch.randn(n, 4, generator=g),
                     torch.randn(n, 3, generator=g) * 0.5 - 4, torch.randn(n, generator=g) * 2, sh)


def _unit(q: torch.Tensor) -> torch.Tensor:
    return q / q.norm(dim=1, keepdim=True)


def _within_spz_quantisation(g: Gaussians, h: Gaussians) -> None:
    """``h`` (read back) equals ``g`` within SPZ's quantisation steps."""
    assert h.num == g.num and h.sh_degree == g.sh_degree
    assert (h.means - g.means).abs().max() <= 0.5 / 4096 + 1e-6  # 12 fractional bits, rounded
    assert (h.log_scales - g.log_scales).abs().max() <= 0.5 / 16 + 1e-5
    assert (torch.sigmoid(h.opacity_logits) - torch.sigmoid(g.opacity_logits)).abs().max() <= 0.5 / 255 + 1e-5
    assert (h.sh[:, 0] - g.sh[:, 0]).abs().max() <= 0.5 / 255 / 0.15 + 1e-5
    assert (_unit(h.quats) * _unit(g.quats)).sum(1).abs().min() >= 0.9995
    assert (h.sh[:, 1:4] - g.sh[:, 1:4]).abs().max() <= 4.5 / 128 + 1e-5  # degree 1: 5 bits (8-bit rounding, then to a bucket of 8)
    assert (h.sh[:, 4:] - g.sh[:, 4:]).abs().max() <= 8.5 / 128 + 1e-5  # degrees 2-3: 4 bits


def test_spz_roundtrip_and_refusals(tmp_path):
    g = _scene()
    save_spz(tmp_path / "a.spz", g)
    _within_spz_quantisation(g, load_spz(tmp_path / "a.spz"))
    assert (tmp_path / "a.spz").read_bytes() == (save_spz(tmp_path / "b.spz", g) or (tmp_path / "b.spz").read_bytes())
    far = _scene(10)
    far.means[0, 0] = 3000.0
    with pytest.raises(ValueError, match="24-bit fixed point"):
        save_spz(tmp_path / "far.spz", far)
    (tmp_path / "v4.spz").write_bytes(b"NGSP" + bytes(28))
    with pytest.raises(ValueError, match="version 4"):
        load_spz(tmp_path / "v4.spz")


@needs_node("splat-transform")
def test_spz_read_by_splat_transform(tmp_path):
    g = _scene()
    save_spz(tmp_path / "a.spz", g)
    splat_transform(tmp_path / "a.spz", tmp_path / "back.ply")
    _within_spz_quantisation(g, load_ply(tmp_path / "back.ply"))


def test_spz_read_by_gsply(tmp_path):
    gsply = pytest.importorskip("gsply", reason="gsply is in the test extra (pip install -e '.[test]')")
    g = _scene()
    save_spz(tmp_path / "a.spz", g)
    d = gsply.read_spz(tmp_path / "a.spz")
    assert np.abs(np.asarray(d.means) - g.means.numpy()).max() <= 0.5 / 4096 + 1e-6
    dots = np.abs((np.asarray(d.quats) * _unit(g.quats).numpy()).sum(1))
    assert dots.min() >= 0.9995  # same w, x, y, z order, no axis flip


def _glb_json_and_bin(path: Path) -> tuple[dict, bytes]:
    raw = path.read_bytes()
    assert raw[:4] == b"glTF" and int.from_bytes(raw[8:12], "little") == len(raw)
    n = int.from_bytes(raw[12:16], "little")
    doc = json.loads(raw[20:20 + n])
    return doc, raw[28 + n:]


def _accessor(doc: dict, binary: bytes, semantic: str) -> np.ndarray:
    prim = doc["meshes"][0]["primitives"][0]
    acc = doc["accessors"][prim["attributes"][semantic]]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = {5126: np.float32, 5121: np.uint8}[acc["componentType"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
    return np.frombuffer(binary, dtype, acc["count"] * width, view["byteOffset"] + acc.get("byteOffset", 0)
                         ).reshape(acc["count"], width)


def test_glb_read_by_pygltflib(tmp_path):
    """pygltflib parses the file; the attributes hold canonical.ply's values (positions exactly)."""
    pygltflib = pytest.importorskip("pygltflib", reason="pygltflib is in the test extra (pip install -e '.[test]')")
    g = _scene(deg=2)
    save_glb(tmp_path / "a.glb", g)
    gl = pygltflib.GLTF2().load(str(tmp_path / "a.glb"))
    binary = gl.binary_blob()
    doc = json.loads(gl.gltf_to_json())
    assert doc["extensionsUsed"] == [EXT] and doc["meshes"][0]["primitives"][0]["mode"] == 0
    assert np.array_equal(_accessor(doc, binary, "POSITION"), g.means.numpy())
    rot = _accessor(doc, binary, f"{EXT}:ROTATION")
    assert np.allclose(rot[:, [3, 0, 1, 2]], _unit(g.quats).numpy(), atol=1e-6)
    assert np.allclose(_accessor(doc, binary, f"{EXT}:SCALE"), g.log_scales.exp().numpy(), rtol=1e-6)
    assert np.allclose(_accessor(doc, binary, f"{EXT}:OPACITY")[:, 0], torch.sigmoid(g.opacity_logits).numpy(), atol=1e-7)
    assert np.array_equal(_accessor(doc, binary, f"{EXT}:SH_DEGREE_2_COEF_4"), g.sh[:, 8].numpy())  # l=2, m=+2
    assert f"{EXT}:SH_DEGREE_3_COEF_0" not in doc["meshes"][0]["primitives"][0]["attributes"]
    # the node stands anigs's +z up as glTF's +y up
    x, y, z, w = doc["nodes"][0]["rotation"]
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert np.allclose(R @ [0, 0, 1], [0, 1, 0]) and np.allclose(R, Y_UP)


_VALIDATE = """
import { validateBytes } from 'gltf-validator';
import { readFileSync } from 'fs';
const r = await validateBytes(new Uint8Array(readFileSync(process.argv[2])), {maxIssues: 1000});
console.log(JSON.stringify(r.issues));
"""


@needs_node("gltf-validator", "splat-transform")
def test_glb_validated_and_like_splat_transforms(tmp_path):
    """Khronos's validator finds no error but the extension's own attribute names (the validator predates
    the extension, which allows them); splat-transform's glb writer stores the same attributes."""
    g = _scene(deg=3)
    save_glb(tmp_path / "a.glb", g)
    issues = json.loads(node_script(_VALIDATE, tmp_path / "a.glb"))
    unexpected = [m for m in issues["messages"] if m["severity"] <= 1 and not (
        m["code"] == "MESH_PRIMITIVE_INVALID_ATTRIBUTE" and m["pointer"].split("/")[-1].startswith(EXT + ":"))]
    assert not unexpected, unexpected
    assert issues["numErrors"] == 4 + 15  # ROTATION, SCALE, OPACITY, SH_DEGREE_0 and the 15 higher coefficients
    g.save_ply(tmp_path / "a.ply")
    splat_transform(tmp_path / "a.ply", tmp_path / "theirs.glb")
    ours, ob = _glb_json_and_bin(tmp_path / "a.glb")
    theirs, tb = _glb_json_and_bin(tmp_path / "theirs.glb")
    attrs = theirs["meshes"][0]["primitives"][0]["attributes"]
    assert set(attrs) == set(ours["meshes"][0]["primitives"][0]["attributes"])
    assert ours["meshes"][0]["primitives"][0]["extensions"] == theirs["meshes"][0]["primitives"][0]["extensions"]
    # splat-transform bakes its engine frame into the data: turned 180 degrees about z, i.e. SuperSplat's
    # (-x, -y, z), with the rotations and the SH coefficients turned alike ((-1)^m per order m)
    for sem in attrs:
        a, b = _accessor(ours, ob, sem), _accessor(theirs, tb, sem)
        if sem == "POSITION":
            a = a @ SUPERSPLAT
        elif sem.endswith(":ROTATION"):  # q -> (0, 0, 1, 0) * q, up to sign (splat-transform does not normalise)
            b = b / np.linalg.norm(b, axis=1, keepdims=True)
            x, y, z, w = a.T
            a = np.stack([-y, x, w, -z], 1) * np.sign(np.sum(np.stack([-y, x, w, -z], 1) * b, 1, keepdims=True))
        elif (m := re.search(r"SH_DEGREE_(\d)_COEF_(\d)", sem)) and m.group(1) != "0":
            a = a * (-1) ** (int(m.group(2)) - int(m.group(1)))
        assert np.allclose(a, b, rtol=1e-5, atol=1.0 if sem == "COLOR_0" else 1e-6), sem


# ---- the orientation, stated once (README) and applied ----------------------------------------

def _readme_rows() -> dict[str, str]:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"### Opening the exports in other tools\n(.*?)\n### ", text, re.S)
    assert m, "README.md has no section '### Opening the exports in other tools'"
    rows = {}
    for line in m.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and len(cells) >= 3 and not set(cells[0]) <= set("-: "):
            rows[cells[0]] = " ".join(cells[1:])
    return rows


def _rotation_about_x(degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def test_readme_orientation_table_matches_the_code():
    """Trap 4: the README says per tool how to stand the +z-up scene upright; each rotation it states
    takes anigs's up (+z) to the tool's up (+y), and SuperSplat's frame is the one the code uses."""
    rows = _readme_rows()
    for tool in ("SuperSplat", "three.js / Spark", "PlayCanvas", "glTF viewers (canonical.glb)"):
        assert tool in rows, f"README orientation table has no row {tool!r}: {list(rows)}"
    for tool in ("three.js / Spark", "PlayCanvas", "SuperSplat"):
        deg = re.search(r"rotat\w* (-?\d+)° about x", rows[tool])
        assert deg, (tool, rows[tool])
        R = _rotation_about_x(float(deg.group(1)))
        assert np.allclose(R, Y_UP) and np.allclose(R @ [0, 0, 1], [0, 1, 0]), tool
    assert "(-x, -y, z)" in rows["SuperSplat"] and np.allclose(SUPERSPLAT @ [1, 2, 3], [-1, -2, 3])
    assert "frame: supersplat" in rows["SuperSplat"]
    assert "no rotation" in rows["glTF viewers (canonical.glb)"] and np.isclose(
        np.linalg.norm(Y_UP_QUAT_XYZW), 1.0)


@needs_node("splat-transform")
def test_compressed_ply_reader_matches_splat_transforms(tmp_path):
    """SuperSplat's compressed PLY (splat-transform's writer, which SuperSplat calls): our reader gives
    what splat-transform's own reader gives, for every attribute, and positions within half a step."""
    from anigs.formats.compressed_ply import is_compressed_ply, read_compressed_ply

    g = _scene(n=1000, deg=2)
    g.save_ply(tmp_path / "a.ply")
    splat_transform(tmp_path / "a.ply", tmp_path / "a.compressed.ply")
    splat_transform(tmp_path / "a.compressed.ply", tmp_path / "theirs.ply")
    assert is_compressed_ply(tmp_path / "a.compressed.ply") and not is_compressed_ply(tmp_path / "a.ply")
    ours, step = read_compressed_ply(tmp_path / "a.compressed.ply")
    theirs = load_ply(tmp_path / "theirs.ply")
    assert ours.num == theirs.num == g.num and ours.sh_degree == theirs.sh_degree == 2
    assert (ours.means - theirs.means).abs().max() <= 1e-5
    assert (ours.log_scales - theirs.log_scales).abs().max() <= 1e-4
    assert (_unit(ours.quats) * _unit(theirs.quats)).sum(1).abs().min() >= 1 - 1e-6
    assert (torch.sigmoid(ours.opacity_logits) - torch.sigmoid(theirs.opacity_logits)).abs().max() <= 1e-5
    assert (ours.sh - theirs.sh).abs().max() <= 1e-4
    # the splats come back reordered (Morton order); each lies within half its step of an original
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(g.means.double().numpy()).query(ours.means.double().numpy())
    assert (dist <= np.linalg.norm(step, axis=1) / 2 + 1e-6).all()
    with pytest.raises(ValueError, match="not a SuperSplat compressed PLY"):
        read_compressed_ply(tmp_path / "a.ply")
