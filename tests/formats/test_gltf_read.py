"""The glb reader (anigs/formats/gltf.py load_glb): anigs's own files back exactly, a file written by
pygltflib with interleaved, normalized and offset accessors under a chain of node transforms, the
COLOR_0 fallback, and the refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from anigs.formats.gltf import EXT, glb_attributes, glb_bytes, glb_document, load_glb, save_glb
from anigs.formats.orientation import Y_UP
from anigs.gaussians import SH_C0, Gaussians
from anigs.geometry.quaternion import quat_to_rotmat
from anigs.geometry.transform import transform_gaussians
from anigs.sfm.align import Similarity


def _scene(n: int = 300, deg: int = 3, seed: int = 0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    sh = torch.randn(n, (deg + 1) ** 2, 3, generator=g) * 0.2
    return Gaussians(torch.rand(n, 3, generator=g) * 6 - 3, torch.randn(n, 4, generator=g),
                     torch.randn(n, 3, generator=g) * 0.5 - 4, torch.randn(n, generator=g) * 2, sh)


def _same_gaussians(a: Gaussians, b: Gaussians, atol: float = 1e-6) -> None:
    assert a.num == b.num and a.sh_degree == b.sh_degree
    assert (a.means - b.means).abs().max() <= atol * max(1.0, float(a.means.abs().max()))
    assert (quat_to_rotmat(a.quats) - quat_to_rotmat(b.quats)).abs().max() <= atol
    assert (a.log_scales - b.log_scales).abs().max() <= atol
    assert (a.opacity_logits - b.opacity_logits).abs().max() <= 1e-4
    assert (a.sh - b.sh).abs().max() <= atol


def test_anigs_glb_reads_back(tmp_path):
    g = _scene()
    save_glb(tmp_path / "a.glb", g)
    h = load_glb(tmp_path / "a.glb")
    stored, back = glb_attributes(g), glb_attributes(h)
    for name in ("POSITION", *(k for k in stored if "SH_DEGREE" in k)):
        assert np.array_equal(back[name], stored[name]), name  # float32 exact
    assert np.array_equal(h.quats.numpy(), stored[f"{EXT}:ROTATION"][:, [3, 0, 1, 2]])  # as stored: x, y, z, w
    assert np.abs(back["COLOR_0"].astype(int) - stored["COLOR_0"]).max() <= 1
    for name in (f"{EXT}:SCALE", f"{EXT}:OPACITY"):  # stored after exp / sigmoid: one float32 rounding
        assert np.allclose(back[name], stored[name], rtol=3e-7, atol=0), name
    assert torch.equal(h.means, g.means) and torch.equal(h.sh, g.sh)
    assert (h.log_scales - g.log_scales).abs().max() <= 1e-6
    assert (torch.sigmoid(h.opacity_logits) - torch.sigmoid(g.opacity_logits)).abs().max() <= 2.5e-7
    # the node's -90 degree turn about x: glTF's world is +y up, (x, y, z) -> (x, z, -y)
    world = load_glb(tmp_path / "a.glb", apply_nodes=True)
    assert torch.allclose(world.means, g.means[:, [0, 2, 1]] * torch.tensor([1.0, 1.0, -1.0]), atol=1e-6)
    _same_gaussians(world, transform_gaussians(h, 1.0, Y_UP, np.zeros(3)))


def _pygltflib_file(path, raw: dict, parent: Similarity, child: Similarity) -> None:
    """A glb written by pygltflib: POSITION and SCALE interleaved (byteStride 24), ROTATION as
    normalized shorts after 8 bytes of padding (accessor byteOffset), OPACITY normalized bytes
    (byteStride 4), SH degrees 0 and 1 as floats; the mesh under a child node (matrix) of a parent
    node (translation, rotation, scale)."""
    pg = pytest.importorskip("pygltflib", reason="pygltflib is in the test extra (pip install -e '.[test]')")
    n = len(raw["pos"])
    inter = np.zeros((n, 6), np.float32)
    inter[:, :3], inter[:, 3:] = raw["pos"], raw["scale"]
    rot = np.concatenate([np.zeros(4, np.int16), raw["rot"].reshape(-1)]).astype("<i2")
    opa = np.zeros((n, 4), np.uint8)
    opa[:, 0] = raw["opacity"]
    blobs = [inter.tobytes(), rot.tobytes(), opa.tobytes(), np.ascontiguousarray(raw["sh"], np.float32).tobytes()]
    offsets = np.cumsum([0] + [len(b) for b in blobs])
    views = [pg.BufferView(buffer=0, byteOffset=int(offsets[0]), byteLength=len(blobs[0]), byteStride=24),
             pg.BufferView(buffer=0, byteOffset=int(offsets[1]), byteLength=len(blobs[1])),
             pg.BufferView(buffer=0, byteOffset=int(offsets[2]), byteLength=len(blobs[2]), byteStride=4),
             pg.BufferView(buffer=0, byteOffset=int(offsets[3]), byteLength=len(blobs[3]))]
    acc = lambda view, ct, typ, off=0, **kw: pg.Accessor(bufferView=view, byteOffset=off, componentType=ct,
                                                          count=n, type=typ, **kw)
    accessors = [acc(0, pg.FLOAT, "VEC3", min=raw["pos"].min(0).tolist(), max=raw["pos"].max(0).tolist()),
                 acc(0, pg.FLOAT, "VEC3", 12), acc(1, pg.SHORT, "VEC4", 8, normalized=True),
                 acc(2, pg.UNSIGNED_BYTE, "SCALAR", normalized=True)]
    accessors += [acc(3, pg.FLOAT, "VEC3", 12 * n * k) for k in range(4)]
    attrs = {"POSITION": 0, f"{EXT}:SCALE": 1, f"{EXT}:ROTATION": 2, f"{EXT}:OPACITY": 3,
             f"{EXT}:SH_DEGREE_0_COEF_0": 4, **{f"{EXT}:SH_DEGREE_1_COEF_{c}": 5 + c for c in range(3)}}
    prim = pg.Primitive(attributes=pg.Attributes(), mode=pg.POINTS,
                        extensions={EXT: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display"}})
    prim.attributes = attrs  # the extension's semantics are not pygltflib.Attributes fields
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = child.scale * child.R, child.t
    x, y, z, w = Rotation.from_matrix(parent.R).as_quat()
    gl = pg.GLTF2(
        scene=0, scenes=[pg.Scene(nodes=[0])],
        nodes=[pg.Node(children=[1], translation=parent.t.tolist(), rotation=[x, y, z, w], scale=[parent.scale] * 3),
               pg.Node(mesh=0, matrix=m.T.reshape(-1).tolist())],
        meshes=[pg.Mesh(primitives=[prim])], accessors=accessors, bufferViews=views,
        buffers=[pg.Buffer(byteLength=int(offsets[-1]))],
        extensionsUsed=[EXT, "KHR_mesh_quantization"], extensionsRequired=["KHR_mesh_quantization"])
    gl.set_binary_blob(b"".join(blobs))
    gl.save_binary(str(path))


def test_glb_written_by_pygltflib_with_node_transforms(tmp_path):
    gen = np.random.default_rng(3)
    n = 50
    q = gen.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    raw = {"pos": gen.uniform(-2, 2, (n, 3)).astype(np.float32), "scale": gen.uniform(0.01, 0.2, (n, 3)).astype(np.float32),
           "rot": np.round(q[:, [1, 2, 3, 0]] * 32767).astype(np.int16), "opacity": gen.integers(1, 255, n, dtype=np.uint8),
           "sh": gen.normal(size=(4, n, 3)).astype(np.float32)}
    parent = Similarity(2.0, Rotation.from_rotvec([0.4, -0.2, 1.1]).as_matrix(), np.array([1.0, 2.0, 3.0]))
    child = Similarity(0.5, Rotation.from_rotvec([0.0, 0.0, math.radians(30)]).as_matrix(), np.array([0.1, -0.2, 0.3]))
    _pygltflib_file(tmp_path / "p.glb", raw, parent, child)

    g = load_glb(tmp_path / "p.glb")
    assert g.num == n and g.sh_degree == 1
    assert torch.equal(g.means, torch.from_numpy(raw["pos"]))
    assert torch.allclose(g.log_scales, torch.from_numpy(np.log(raw["scale"].astype(np.float64))).float())
    assert torch.allclose(g.quats, torch.from_numpy(raw["rot"][:, [3, 0, 1, 2]] / 32767).float(), atol=1e-7)
    assert torch.allclose(torch.sigmoid(g.opacity_logits), torch.from_numpy(raw["opacity"] / 255).float(), atol=1e-6)
    assert torch.equal(g.sh, torch.from_numpy(raw["sh"]).transpose(0, 1))

    world = parent.compose(child)
    expected = transform_gaussians(g, world.scale, world.R, world.t)
    _same_gaussians(load_glb(tmp_path / "p.glb", apply_nodes=True), expected, atol=1e-5)
    assert torch.allclose(expected.means, torch.from_numpy(world.apply(raw["pos"])).float(), atol=1e-5)


def _write(path, g: Gaussians, edit) -> None:
    doc, binary = glb_document(g)
    edit(doc)
    path.write_bytes(glb_bytes(doc, binary))


def _prim(doc: dict) -> dict:
    return doc["meshes"][0]["primitives"][0]


def test_color_0_fallback(tmp_path):
    g = _scene(40, deg=0)
    rgb = (g.sh[:, 0].double() * SH_C0 + 0.5).clamp(0, 1)

    def linear_colours(doc):
        del _prim(doc)["attributes"][f"{EXT}:SH_DEGREE_0_COEF_0"]
        _prim(doc)["extensions"][EXT]["colorSpace"] = "lin_rec709_display"

    _write(tmp_path / "lin.glb", g, linear_colours)
    h = load_glb(tmp_path / "lin.glb")
    assert h.sh_degree == 0 and (h.rgb - rgb).abs().max() <= 0.5 / 255 + 1e-6  # COLOR_0: 8 bits
    _write(tmp_path / "srgb.glb", g, lambda doc: _prim(doc)["attributes"].pop(f"{EXT}:SH_DEGREE_0_COEF_0"))
    lin = torch.from_numpy(glb_attributes(g)["COLOR_0"][:, :3] / 255.0)
    srgb = torch.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)  # glTF colours are linear
    assert (load_glb(tmp_path / "srgb.glb").rgb.double() - srgb).abs().max() <= 1e-6


def _attr(doc: dict, name: str) -> dict:
    return doc["accessors"][_prim(doc)["attributes"][name]]


REFUSALS = [
    ("no_extension", lambda d: _prim(d).pop("extensions"), "no mesh primitive with the KHR_gaussian_splatting"),
    ("missing", lambda d: _prim(d)["attributes"].pop(f"{EXT}:OPACITY"), "missing attributes"),
    ("no_colour", lambda d: [_prim(d)["attributes"].pop(k) for k in ("COLOR_0", f"{EXT}:SH_DEGREE_0_COEF_0")],
     "missing attributes"),
    ("partial_sh", lambda d: _prim(d)["attributes"].pop(f"{EXT}:SH_DEGREE_1_COEF_2"), "SH degree 1"),
    ("sparse", lambda d: _attr(d, "POSITION").update(sparse={"count": 1}), "sparse accessors"),
    ("draco", lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]), "KHR_draco_mesh_compression"),
    ("draco_primitive", lambda d: _prim(d).update(extensions={EXT: {}, "KHR_draco_mesh_compression": {}}),
     "KHR_draco_mesh_compression"),
    ("meshopt", lambda d: d["bufferViews"][0].update(extensions={"EXT_meshopt_compression": {}}),
     "EXT_meshopt_compression"),
    ("spz_in_glb", lambda d: _prim(d)["extensions"][EXT].update(extensions={"KHR_gaussian_splatting_compression_spz_2": {}}),
     "KHR_gaussian_splatting_compression_spz_2"),
    ("past_the_end", lambda d: _attr(d, "POSITION").update(byteOffset=8), "past its buffer view"),
]


@pytest.mark.parametrize("name,edit,message", REFUSALS, ids=[r[0] for r in REFUSALS])
def test_refusals(tmp_path, name, edit, message):
    _write(tmp_path / f"{name}.glb", _scene(20, deg=1), edit)
    with pytest.raises(ValueError, match=message):
        load_glb(tmp_path / f"{name}.glb")


def test_refuses_what_is_not_a_glb_and_non_similar_nodes(tmp_path):
    (tmp_path / "a.glb").write_bytes(b"ply\nformat binary_little_endian 1.0\n")
    with pytest.raises(ValueError, match="not a glb"):
        load_glb(tmp_path / "a.glb")
    _write(tmp_path / "b.glb", _scene(20), lambda d: d["nodes"][0].update(scale=[1.0, 2.0, 1.0]))
    assert load_glb(tmp_path / "b.glb").num == 20  # the stored values need no node
    with pytest.raises(ValueError, match="non-uniform"):
        load_glb(tmp_path / "b.glb", apply_nodes=True)
    _write(tmp_path / "c.glb", _scene(20), lambda d: d["nodes"][0].update(scale=[-1.0, -1.0, -1.0]))
    with pytest.raises(ValueError, match="mirror"):
        load_glb(tmp_path / "c.glb", apply_nodes=True)
