"""Gaussian set and the standard 3DGS PLY layout."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.gaussians import Gaussians, load_ply, ply_property_names, save_ply


def _random(n=50, deg=3, seed=0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    return Gaussians(torch.randn(n, 3, generator=g), torch.randn(n, 4, generator=g), torch.randn(n, 3, generator=g),
                     torch.randn(n, generator=g), torch.randn(n, (deg + 1) ** 2, 3, generator=g))


@pytest.mark.parametrize("deg", [0, 1, 2, 3])
def test_ply_roundtrip_is_exact(tmp_path, deg):
    g = _random(deg=deg, seed=deg)
    save_ply(g, tmp_path / "a.ply")
    h = load_ply(tmp_path / "a.ply")
    assert h.sh_degree == deg
    for k, v in g.params().items():
        assert torch.equal(v, h.params()[k]), k


def test_reads_ply_written_by_another_tool(tmp_path):
    """A file as the original 3DGS code writes it (via plyfile), with the properties shuffled
    and an extra element: values land in the right fields and f_rest is channel-major."""
    plyfile = pytest.importorskip("plyfile")
    n, deg = 20, 2
    c = (deg + 1) ** 2
    rng = np.random.default_rng(0)
    names = ply_property_names(deg)
    cols = {k: rng.standard_normal(n).astype(np.float32) for k in names}
    order = names[::-1]  # reversed property order
    arr = np.empty(n, dtype=[(k, "f4") for k in order] + [("red", "u1")])
    for k in order:
        arr[k] = cols[k]
    arr["red"] = 7
    faces = np.array([([0, 1, 2],)], dtype=[("vertex_indices", "i4", (3,))])
    plyfile.PlyData([plyfile.PlyElement.describe(arr, "vertex"), plyfile.PlyElement.describe(faces, "face")]).write(
        str(tmp_path / "other.ply"))
    g = load_ply(tmp_path / "other.ply")
    assert g.sh_degree == deg
    assert np.allclose(g.means[:, 1].numpy(), cols["y"])
    assert np.allclose(g.opacity_logits.numpy(), cols["opacity"])
    assert np.allclose(g.quats[:, 3].numpy(), cols["rot_3"])
    # channel-major f_rest: coefficient k of channel ch is f_rest_{ch*(c-1) + k-1}
    assert np.allclose(g.sh[:, 2, 1].numpy(), cols[f"f_rest_{1 * (c - 1) + 1}"])
    assert np.allclose(g.sh[:, 0, 2].numpy(), cols["f_dc_2"])


def test_ascii_ply(tmp_path):
    names = ply_property_names(0)
    lines = ["ply", "format ascii 1.0", "element vertex 2"] + [f"property float {k}" for k in names] + ["end_header"]
    lines += [" ".join(str(float(i + j)) for j in range(len(names))) for i in range(2)]
    (tmp_path / "a.ply").write_text("\n".join(lines) + "\n")
    g = load_ply(tmp_path / "a.ply")
    assert g.num == 2 and g.means[1, 0] == 1.0 and g.quats[0, 3] == len(names) - 1


def test_bad_ply_errors(tmp_path):
    (tmp_path / "x.ply").write_bytes(b"not a ply")
    with pytest.raises(ValueError, match="not a PLY"):
        load_ply(tmp_path / "x.ply")
    with pytest.raises(FileNotFoundError):
        load_ply(tmp_path / "missing.ply")
    save_ply(_random(deg=1), tmp_path / "t.ply")
    data = (tmp_path / "t.ply").read_bytes()
    (tmp_path / "t.ply").write_bytes(data[:-10])
    with pytest.raises(ValueError, match="truncated"):
        load_ply(tmp_path / "t.ply")


def test_shape_checks_and_finiteness():
    g = _random(n=5, deg=0)
    with pytest.raises(ValueError, match="quats"):
        Gaussians(g.means, g.quats[:3], g.log_scales, g.opacity_logits, g.sh)
    g.means[2, 1] = float("nan")
    with pytest.raises(ValueError, match="means"):
        g.check_finite()


def test_activations_and_concat():
    g = Gaussians.from_points(torch.zeros(3, 3), torch.tensor([[1.0, 0, 0]] * 3), scales=0.5, opacity=0.25)
    assert torch.allclose(g.scales, torch.full((3, 3), 0.5))
    assert torch.allclose(g.opacities, torch.full((3,), 0.25))
    assert torch.allclose(g.rgb, torch.tensor([[1.0, 0, 0]] * 3), atol=1e-6)
    h = Gaussians.concat([g, _random(n=4, deg=2)])
    assert h.num == 7 and h.sh_degree == 2
