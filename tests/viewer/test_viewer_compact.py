"""Compact animated format (anigs.viewer.compact), viewer folder, server and CLI."""
from __future__ import annotations

import argparse
import base64
import json
import math
import re
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import torch

from anigs.animate.deform import DCTDeformation, load_model, save_model
from anigs.animate.frames import deformed
from anigs.gaussians import Gaussians, load_ply
from anigs.stages import view as viewer_cli
from anigs.stages.command import stage_arguments
from anigs.stages.view import Outputs as ViewOutputs
from anigs.viewer.build import build_viewer
from anigs.viewer.compact import (
    CompactFormatError,
    decode_compact,
    encode_compact,
    load_compact,
    save_compact,
    write_frame_plys,
)
from anigs.viewer.serve import start_server

FIELDS = ("means", "quats", "log_scales", "opacity_logits", "sh")


def animated_scene(n: int = 600, d: int = 90, T: int = 9, K: int = 4, sh_degree: int = 3, rotation: bool = True,
                   limits: bool = False, seed: int = 0, scale_range: tuple[float, float] = (0.01, 0.06),
                   ) -> tuple[Gaussians, DCTDeformation]:
    """Random canonical scene [n] in [-1,1]^3 with d dynamic Gaussians carrying random DCT coefficients."""
    g = torch.Generator().manual_seed(seed)
    means = torch.rand(n, 3, generator=g) * 2 - 1
    log_scales = torch.empty(n, 3).uniform_(math.log(scale_range[0]), math.log(scale_range[1]), generator=g)
    sh = torch.randn(n, (sh_degree + 1) ** 2, 3, generator=g) * 0.2
    canonical = Gaussians(means, torch.randn(n, 4, generator=g), log_scales, torch.randn(n, generator=g), sh)
    idx = torch.randperm(n, generator=g)[:d]
    lim = (lambda v: torch.full((d,), v)) if limits else (lambda v: None)
    deformation = DCTDeformation(idx, T, K, rotation=rotation, max_offset=lim(0.03), max_angle=lim(0.2),
                                 num_gaussians=n)
    with torch.no_grad():
        deformation.pos_coeffs.copy_(torch.randn(d, 3, K, generator=g) * 0.05)
        if rotation:
            deformation.rot_coeffs.copy_(torch.randn(d, 3, K, generator=g) * 0.3)
    return canonical, deformation


def assert_same(a: Gaussians, b: Gaussians) -> None:
    for f in FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and torch.equal(x, y), f"{f} differs"


@pytest.mark.parametrize("rotation,limits,sh_degree", [(True, False, 3), (False, False, 0), (True, True, 1)])
def test_round_trip_is_exact_at_integer_and_fractional_times(rotation, limits, sh_degree):
    canonical, deformation = animated_scene(rotation=rotation, limits=limits, sh_degree=sh_degree)
    scene = decode_compact(encode_compact(canonical, deformation, fps=10.0))
    assert scene.header["num_dynamic"] == deformation.num_dynamic and scene.header["fps"] == 10.0
    assert_same(scene.canonical, canonical)
    static = torch.ones(canonical.num, dtype=torch.bool)
    static[deformation.dynamic_index] = False
    for t in (0, 1, 2.5, 3.75, 7.125, 8):
        ours, lib = scene.frame(t), deformation(canonical, t)
        assert_same(ours, lib)
        # static rows are the canonical values bit for bit; the dynamic ones really move
        assert torch.equal(ours.means[static], canonical.means[static])
        assert torch.equal(ours.quats[static], canonical.quats[static])
        assert not torch.equal(ours.means[~static], canonical.means[~static])
        if rotation:
            assert not torch.equal(ours.quats[~static], canonical.quats[~static])


def test_round_trip_through_model_checkpoint(tmp_path):
    """model.pt + canonical PLY -> compact file -> frames equal the library's frames of model.pt."""
    canonical, deformation = animated_scene(n=400, d=50)
    trained = Gaussians(canonical.means + 0.01, canonical.quats, canonical.log_scales,
                        canonical.opacity_logits, canonical.sh)  # trained positions differ from the PLY
    canonical.save_ply(tmp_path / "canonical.ply")
    save_model(tmp_path / "model.pt", deformation, trained)
    lib_canonical, lib_deformation, _ = load_model(tmp_path / "model.pt", tmp_path / "canonical.ply")
    header = save_compact(tmp_path / "scene.anigs", lib_canonical, lib_deformation)
    assert header["num_gaussians"] == 400 and header["num_dynamic"] == 50
    scene = load_compact(tmp_path / "scene.anigs")
    for t in (0, 4, 6.5):
        assert_same(scene.frame(t), deformed(lib_canonical, lib_deformation, t))
    assert_same(scene.frame(0), deformed(trained, deformation, 0))


def test_no_dynamic_gaussians():
    canonical, _ = animated_scene(n=50, d=5)
    empty = DCTDeformation(torch.zeros(0, dtype=torch.long), 9, 4, num_gaussians=50)
    scene = decode_compact(encode_compact(canonical, empty))
    assert scene.deformation.num_dynamic == 0
    assert_same(scene.frame(3.5), canonical)


def test_bad_files_give_clear_errors(tmp_path):
    canonical, deformation = animated_scene(n=100, d=10)
    blob = encode_compact(canonical, deformation)
    with pytest.raises(CompactFormatError, match="not an anigs compact scene"):
        decode_compact(b"ply\nformat binary_little_endian 1.0\n" + blob[40:])
    with pytest.raises(CompactFormatError, match="truncated"):
        decode_compact(blob[:-100])
    with pytest.raises(CompactFormatError, match="truncated|too short"):
        decode_compact(blob[:10])
    flipped = bytearray(blob)
    flipped[-5] ^= 0xFF
    with pytest.raises(CompactFormatError, match="corrupted"):
        decode_compact(bytes(flipped))
    newer = bytearray(blob)
    newer[8] = 7
    with pytest.raises(CompactFormatError, match="version 7"):
        decode_compact(bytes(newer))
    with pytest.raises(FileNotFoundError):
        load_compact(tmp_path / "missing.anigs")
    (tmp_path / "cut.anigs").write_bytes(blob[: len(blob) // 2])
    with pytest.raises(CompactFormatError, match="cut.anigs.*truncated"):
        load_compact(tmp_path / "cut.anigs")


def test_layout_is_documented_little_endian(tmp_path):
    """The arrays sit where the header says, 16-byte aligned, in the documented dtypes."""
    canonical, deformation = animated_scene(n=120, d=12, K=3)
    blob = encode_compact(canonical, deformation)
    assert blob[:8] == b"ANIGSCMP"
    hlen = int.from_bytes(blob[12:16], "little")
    header = json.loads(blob[16:16 + hlen])
    start = 16 + hlen
    assert start % 16 == 0
    for spec in header["arrays"].values():
        assert spec["offset"] % 16 == 0 and spec["dtype"] in ("<f4", "<u4")
    spec = header["arrays"]["pos_coeffs"]
    raw = torch.frombuffer(bytearray(blob[start + spec["offset"]:start + spec["offset"] + spec["nbytes"]]),
                           dtype=torch.float32).reshape(spec["shape"])
    assert torch.equal(raw, deformation.pos_coeffs.detach())


def test_compact_is_smaller_than_frame_plys_and_frames_match(tmp_path):
    canonical, deformation = animated_scene(n=800, d=100, T=9, K=4)
    save_compact(tmp_path / "scene.anigs", canonical, deformation)
    names = write_frame_plys(tmp_path, canonical, deformation, frame_step=2)
    assert names == [f"frames/frame_{t:04d}.ply" for t in (0, 2, 4, 6, 8)]
    frames_bytes = sum((tmp_path / n).stat().st_size for n in names)
    compact_bytes = (tmp_path / "scene.anigs").stat().st_size
    assert compact_bytes * 4 < frames_bytes  # 5 PLYs of the full scene vs one canonical + 100 rows of motion
    assert_same(load_ply(tmp_path / names[2]), deformation(canonical, 4))
    with pytest.raises(ValueError, match="frame_step"):
        write_frame_plys(tmp_path, canonical, deformation, frame_step=0)


def _views_json(path: Path) -> Path:
    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    K = intrinsics_from_fov(60, 96, 72)
    cams = [Camera(K, look_at([0.5, -3.5, 1.2], [0, 0, 0]), 96, 72, "L0_yaw+0"),
            Camera(K, look_at([3.0, 0.5, 0.8], [0, 0, 0]), 96, 72, "L0_yaw+90")]
    path.write_text(json.dumps({"views": [{"id": c.name, "camera": c.to_dict()} for c in cams],
                                "up": [0, 0, 1], "roi_centroid": [0, 0, 0]}))
    return path


def test_build_viewer_folder(tmp_path):
    canonical, deformation = animated_scene(n=300, d=30)
    canonical.save_ply(tmp_path / "canonical.ply")
    save_model(tmp_path / "model.pt", deformation, canonical)
    views = _views_json(tmp_path / "views.json")
    out = tmp_path / "viewer"
    summary = build_viewer(tmp_path / "model.pt", ViewOutputs(out), views, canonical=tmp_path / "canonical.ply",
                           background=[0.1, 0.2, 0.3], fps=8.0)
    for name in ("index.html", "viewer.js", "sort-worker.js", "renderer.js", "scene.anigs", "scene.js", "config.js"):
        assert (out / name).is_file(), name
    html = (out / "index.html").read_text()
    assert "http://" not in html and "https://" not in html  # nothing from a CDN
    for src in re.findall(r'src="([^"]+)"', html):
        assert (out / src).is_file(), src
    cfg = json.loads(re.match(r"window\.ANIGS_CONFIG = (.*);\s*$", (out / "config.js").read_text(), re.DOTALL).group(1))
    assert cfg["views"][0]["id"] == "L0_yaw+0" and cfg["background"] == [0.1, 0.2, 0.3] and cfg["fps"] == 8.0
    assert cfg["views"][0]["camera"]["viewmat"] == json.loads(views.read_text())["views"][0]["camera"]["viewmat"]
    blob = (out / "scene.anigs").read_bytes()
    embedded = re.match(r'window\.ANIGS_SCENE_B64 = "([A-Za-z0-9+/=]+)";\s*$', (out / "scene.js").read_text())
    assert base64.b64decode(embedded.group(1)) == blob
    assert_same(decode_compact(blob).frame(2.5), deformation(canonical, 2.5))
    assert summary["num_views"] == 2 and summary["scene_bytes"] == len(blob)
    # a compact file is also accepted as the input, and embed=False drops scene.js
    build_viewer(out / "scene.anigs", ViewOutputs(tmp_path / "v2"), None, embed=False)
    assert not (tmp_path / "v2" / "scene.js").exists()
    assert_same(load_compact(tmp_path / "v2" / "scene.anigs").frame(1), deformation(canonical, 1))
    with pytest.raises(ValueError, match="canonical PLY"):
        build_viewer(tmp_path / "model.pt", ViewOutputs(tmp_path / "v3"))  # positions only: needs the PLY


def test_server_serves_folder_on_loopback_and_stops(tmp_path):
    canonical, deformation = animated_scene(n=100, d=10)
    save_compact(tmp_path / "scene.anigs", canonical, deformation)
    build_viewer(tmp_path / "scene.anigs", ViewOutputs(tmp_path / "viewer"))
    with pytest.raises(ValueError, match="loopback"):
        start_server(ViewOutputs(tmp_path / "viewer"), host="0.0.0.0")
    with pytest.raises(FileNotFoundError):
        start_server(ViewOutputs(tmp_path))
    server = start_server(ViewOutputs(tmp_path / "viewer"))
    try:
        assert server.url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(server.url, timeout=10) as r:
            assert b"<canvas" in r.read()
        with urllib.request.urlopen(server.url.replace("index.html", "scene.anigs"), timeout=10) as r:
            assert r.read() == (tmp_path / "viewer" / "scene.anigs").read_bytes()
    finally:
        server.stop()
    with pytest.raises((urllib.error.URLError, ConnectionError, OSError)):
        urllib.request.urlopen(server.url, timeout=3)


def test_cli_builds_viewer(tmp_path, capsys):
    canonical, deformation = animated_scene(n=100, d=10)
    canonical.save_ply(tmp_path / "static" / "canonical.ply")
    save_model(tmp_path / "model" / "model.pt", deformation, canonical)
    (tmp_path / "views").mkdir()
    _views_json(tmp_path / "views" / "views.json")
    parser = argparse.ArgumentParser()
    stage_arguments(viewer_cli, "view", parser)
    args = parser.parse_args(["--model", str(tmp_path / "model"), "--static", str(tmp_path / "static"),
                              "--views", str(tmp_path / "views"), "--out", str(tmp_path / "v"),
                              "--params", '{"fps": 6, "embed": false}'])
    assert viewer_cli.main(args) == 0
    assert json.loads(capsys.readouterr().out)["num_dynamic"] == 10
    assert (tmp_path / "v" / "index.html").is_file() and not (tmp_path / "v" / "scene.js").exists()
    bad = parser.parse_args(["--model", str(tmp_path / "model"), "--out", str(tmp_path / "w"),
                             "--params", '{"colour": 1}'])
    with pytest.raises(KeyError, match="colour"):
        viewer_cli.main(bad)
