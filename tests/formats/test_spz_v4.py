"""SPZ version 4 (NGSP header, zstd streams) in anigs/formats/spz.py load_spz: files written by gsply
and built by hand read as the same data in version 3 does; versions 2-3 still read; the refusals."""
from __future__ import annotations

import gzip
import struct
import sys

import numpy as np
import pytest
import torch

from anigs.formats.spz import NGSP_V4, load_spz, save_spz, spz_bytes
from anigs.gaussians import Gaussians, save_ply

zstandard = pytest.importorskip("zstandard", reason="zstandard is in the test extra (pip install -e '.[test]')")


def _scene(n: int = 500, deg: int = 3, seed: int = 0) -> Gaussians:
    g = torch.Generator().manual_seed(seed)
    sh = torch.randn(n, (deg + 1) ** 2, 3, generator=g) * 0.2
    return Gaussians(torch.rand(n, 3, generator=g) * 6 - 3, torch.randn(n, 4, generator=g),
                     torch.randn(n, 3, generator=g) * 0.5 - 4, torch.randn(n, generator=g) * 2, sh)


def _equal(a: Gaussians, b: Gaussians) -> None:
    for k, v in a.params().items():
        assert torch.equal(v, b.params()[k]), k


def _v4_from_v3(v3: bytes, extension: bytes = b"") -> bytes:
    """The version 4 file of an uncompressed version 3 payload ``v3`` (header and six blocks)."""
    _, _, n = struct.unpack_from("<III", v3)
    deg, frac = v3[12], v3[13]
    sizes = [9 * n, n, 3 * n, 3 * n, 4 * n, 3 * ((deg + 1) ** 2 - 1) * n]
    offsets = np.cumsum([16] + sizes)
    blocks = [v3[o:o + s] for o, s in zip(offsets, sizes) if s]
    packed = [zstandard.ZstdCompressor(level=3).compress(b) for b in blocks]
    toc_at = NGSP_V4.size + len(extension)
    header = NGSP_V4.pack(0x5053474E, 4, n, deg, frac, 2 if extension else 0, len(blocks), toc_at)
    toc = b"".join(struct.pack("<QQ", len(p), len(b)) for p, b in zip(packed, blocks))
    return header + extension + toc + b"".join(packed)


@pytest.mark.parametrize("deg", [0, 1, 3])
def test_hand_built_v4_reads_as_v3(tmp_path, deg):
    g = _scene(deg=deg)
    save_spz(tmp_path / "a.spz", g)
    (tmp_path / "b.spz").write_bytes(_v4_from_v3(spz_bytes(g)))
    (tmp_path / "c.spz").write_bytes(_v4_from_v3(spz_bytes(g), extension=b"\x01\x00\x00\x00tagged"))
    v3 = load_spz(tmp_path / "a.spz")
    _equal(load_spz(tmp_path / "b.spz"), v3)
    _equal(load_spz(tmp_path / "c.spz"), v3)  # extension records between header and TOC are skipped


def test_v4_written_by_gsply(tmp_path):
    gsply = pytest.importorskip("gsply", reason="gsply is in the test extra (pip install -e '.[test]')")
    g = _scene()
    save_ply(g, tmp_path / "a.ply")
    data = gsply.plyread(str(tmp_path / "a.ply"))
    gsply.write_spz(tmp_path / "v3.spz", data, version=3)
    gsply.write_spz(tmp_path / "v4.spz", data, version=4)
    assert (tmp_path / "v4.spz").read_bytes()[:4] == b"NGSP"
    h = load_spz(tmp_path / "v4.spz")
    _equal(h, load_spz(tmp_path / "v3.spz"))
    assert h.num == g.num and h.sh_degree == 3
    assert (h.means - g.means).abs().max() <= 0.5 / 4096 + 1e-6
    assert (h.sh[:, 0] - g.sh[:, 0]).abs().max() <= 0.5 / 255 / 0.15 + 1e-5
    assert (h.sh[:, 1:] - g.sh[:, 1:]).abs().max() <= 0.5 / 128 + 1e-5  # gsply keeps 8 bits for every degree
    ref = gsply.read_spz(tmp_path / "v4.spz")
    assert np.abs(np.asarray(ref.means) - h.means.numpy()).max() <= 1e-6
    assert np.abs(np.abs((np.asarray(ref.quats) * h.quats.numpy()).sum(1)) - 1).max() <= 1e-5


def test_version_2_still_reads(tmp_path):
    g = _scene(50, deg=1)
    v3 = bytearray(spz_bytes(g))
    n = g.num
    v3[4:8] = struct.pack("<I", 2)
    xyz = np.round((torch.nn.functional.normalize(g.quats, dim=1) * torch.sign(g.quats[:, :1]))[:, 1:].numpy()
                   * 127.5 + 127.5).astype(np.uint8)
    at = 16 + 9 * n + n + 3 * n + 3 * n
    v2 = bytes(v3[:at]) + xyz.tobytes() + bytes(v3[at + 4 * n:])
    (tmp_path / "v2.spz").write_bytes(gzip.compress(v2))
    h = load_spz(tmp_path / "v2.spz")
    q = torch.nn.functional.normalize(g.quats, dim=1)
    assert (h.quats * q).sum(1).abs().min() >= 0.99  # 8 bits of x, y, z; w rebuilt (coarse when small)
    save_spz(tmp_path / "v3.spz", g)
    v3_read = load_spz(tmp_path / "v3.spz")
    assert torch.equal(h.means, v3_read.means) and torch.equal(h.sh, v3_read.sh)


def test_refusals(tmp_path, monkeypatch):
    good = _v4_from_v3(spz_bytes(_scene(20)))
    (tmp_path / "zero.spz").write_bytes(b"NGSP" + bytes(28))
    with pytest.raises(ValueError, match="version 4"):
        load_spz(tmp_path / "zero.spz")
    (tmp_path / "streams.spz").write_bytes(good[:15] + bytes([3]) + good[16:])  # 3 streams announced, 6 there
    with pytest.raises(ValueError, match="streams"):
        load_spz(tmp_path / "streams.spz")
    (tmp_path / "short.spz").write_bytes(good[:-10])
    with pytest.raises(ValueError, match="stream 5"):
        load_spz(tmp_path / "short.spz")
    (tmp_path / "deg4.spz").write_bytes(good[:12] + bytes([4]) + good[13:])
    with pytest.raises(ValueError, match="SH degree 4"):
        load_spz(tmp_path / "deg4.spz")
    (tmp_path / "good.spz").write_bytes(good)
    monkeypatch.setitem(sys.modules, "zstandard", None)  # as if it were not installed
    with pytest.raises(ValueError, match="pip install zstandard"):
        load_spz(tmp_path / "good.spz")
