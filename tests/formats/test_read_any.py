"""read_splat_file (anigs/formats/splats.py): one entry for every splat format anigs reads, by the
suffix or, for another suffix, by the file's first bytes; antimatter15's .splat records."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.formats.gltf import save_glb
from anigs.formats.splats import SPLAT_RECORD, load_splat, read_splat_file
from anigs.formats.spz import load_spz, save_spz
from anigs.gaussians import SH_C0, Gaussians, save_ply


def _scene(n: int = 200, deg: int = 2, seed: int = 0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    sh = torch.randn(n, (deg + 1) ** 2, 3, generator=g) * 0.2
    return Gaussians(torch.rand(n, 3, generator=g) * 6 - 3, torch.randn(n, 4, generator=g),
                     torch.randn(n, 3, generator=g) * 0.5 - 4, torch.randn(n, generator=g) * 2, sh)


def _splat_bytes(g: Gaussians) -> bytes:
    """antimatter15's .splat records of ``g`` (position, linear scale, RGBA, quaternion w,x,y,z)."""
    rec = np.zeros(g.num, SPLAT_RECORD)
    rec["position"] = g.means.numpy()
    rec["scale"] = g.log_scales.exp().numpy()
    rgba = torch.cat([g.sh[:, 0] * SH_C0 + 0.5, torch.sigmoid(g.opacity_logits)[:, None]], 1)
    rec["rgba"] = np.clip(np.round(rgba.numpy() * 255), 0, 255)
    q = torch.nn.functional.normalize(g.quats, dim=1).numpy()
    rec["rot"] = np.clip(np.round(q * 128 + 128), 0, 255)
    return rec.tobytes()


def test_ply(tmp_path):
    g = _scene()
    save_ply(g, tmp_path / "a.ply")
    h, fmt = read_splat_file(tmp_path / "a.ply")
    assert fmt == "ply" and all(torch.equal(v, h.params()[k]) for k, v in g.params().items())


def test_compressed_ply(tmp_path):
    gsply = pytest.importorskip("gsply", reason="gsply is in the test extra (pip install -e '.[test]')")
    g = _scene(600)
    save_ply(g, tmp_path / "a.ply")
    gsply.plywrite(tmp_path / "b.compressed.ply", gsply.plyread(str(tmp_path / "a.ply")), compressed=True)
    h, fmt = read_splat_file(tmp_path / "b.compressed.ply")
    assert fmt == "compressed ply" and h.num == g.num
    extent = float((g.means.max(0).values - g.means.min(0).values).max())
    assert (h.means - g.means).abs().max() <= extent / 1023  # 11/10/11 bits of each 256-splat chunk's box


def test_spz(tmp_path):
    g = _scene()
    save_spz(tmp_path / "a.spz", g)
    h, fmt = read_splat_file(tmp_path / "a.spz")
    assert fmt == "spz" and torch.equal(h.means, load_spz(tmp_path / "a.spz").means)


def test_glb_as_stored(tmp_path):
    g = _scene()
    save_glb(tmp_path / "a.glb", g)
    h, fmt = read_splat_file(tmp_path / "a.glb")
    assert fmt == "glb" and torch.equal(h.means, g.means) and torch.equal(h.sh, g.sh)  # anigs's frame, not +y up


def test_splat(tmp_path):
    g = _scene(deg=0)
    (tmp_path / "a.splat").write_bytes(_splat_bytes(g))
    h, fmt = read_splat_file(tmp_path / "a.splat")
    assert fmt == "splat" and h.num == g.num and h.sh_degree == 0
    assert torch.equal(h.means, g.means)
    assert (h.log_scales - g.log_scales).abs().max() <= 1e-6
    assert (h.rgb - g.rgb.clamp(0, 1)).abs().max() <= 0.5 / 255 + 1e-6
    assert (torch.sigmoid(h.opacity_logits) - torch.sigmoid(g.opacity_logits)).abs().max() <= 0.5 / 255 + 1e-6
    dots = (h.quats * torch.nn.functional.normalize(g.quats, dim=1)).sum(1).abs()
    assert dots.min() >= 0.999 and (h.quats.norm(dim=1) - 1).abs().max() <= 1e-6
    (tmp_path / "bad.splat").write_bytes(_splat_bytes(g)[:-5])
    with pytest.raises(ValueError, match="32-byte"):
        load_splat(tmp_path / "bad.splat")


def test_other_suffix_by_content_and_refusals(tmp_path):
    g = _scene(20)
    save_glb(tmp_path / "scene.bin", g)
    save_spz(tmp_path / "scene.dat", g)
    assert read_splat_file(tmp_path / "scene.bin")[1] == "glb"
    assert read_splat_file(tmp_path / "scene.dat")[1] == "spz"
    (tmp_path / "scene.xyz").write_bytes(b"\x00" * 64)
    with pytest.raises(ValueError, match=r"\.ply, \.spz, \.glb, \.splat"):
        read_splat_file(tmp_path / "scene.xyz")
    with pytest.raises(FileNotFoundError):
        read_splat_file(tmp_path / "missing.ply")
