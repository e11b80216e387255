"""The update's target clips are read from disk a frame at a time: the same values as the whole
clip loaded as float32, the same training, and memory bounded by a frame, not by the clips."""
from __future__ import annotations

import io
import tracemalloc
import zipfile

import numpy as np
import pytest
import torch

from anigs.animate.frames import render_clip
from anigs.animate.target_frames import ClipFrames
from anigs.animate.training_views import load_reference, training_views
from anigs.animate.update import ViewData, run_update
from anigs.animate.config import UpdateConfig
from anigs.io import write_npz
from anigs.video import load_clip, save_clip
from tests._scenes import ring_cameras, sway_motion, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")


def _random_clip(path, T=6, H=20, W=28, seed=0, camera=None):
    clip = np.random.default_rng(seed).random((T, H, W, 3), dtype=np.float32)
    save_clip(path, clip, {"camera": camera.to_dict() if camera else {"name": "v"}, "fps": 8})
    return clip


def test_frames_equal_load_clip_bit_for_bit(tmp_path):
    p = tmp_path / "c.npz"
    _random_clip(p)
    whole, meta = load_clip(p)
    frames = ClipFrames(p)
    assert frames.shape == whole.shape and frames.ndim == 4 and frames.meta == meta and frames.held_bytes == 0
    for t in range(whole.shape[0]):
        f = frames[t]
        assert f.dtype == torch.float32 and np.array_equal(f.numpy(), whole[t])
    assert np.array_equal(frames[-1].numpy(), whole[-1])
    with pytest.raises(IndexError):
        frames[whole.shape[0]]
    ref = load_reference(p)
    assert ref.dtype == torch.float32 and np.array_equal(ref.numpy(), whole[0])


def test_deflated_and_float32_clips_read_the_same(tmp_path):
    clip = np.random.default_rng(1).random((4, 10, 12, 3), dtype=np.float32)
    for dtype, compress in ((np.float16, True), (np.float32, False), (np.float32, True)):
        p = tmp_path / f"c-{np.dtype(dtype).name}-{compress}.npz"
        write_npz(p, compress=compress, frames=clip.astype(dtype), meta=np.array("{}"))
        frames, whole = ClipFrames(p), load_clip(p)[0]
        assert (frames.held_bytes > 0) == compress
        assert all(np.array_equal(frames[t].numpy(), whole[t]) for t in range(4))


def test_bad_clips_give_clear_errors(tmp_path):
    bad = np.zeros((3, 4, 5, 3), np.float16)
    bad[2, 1, 1, 0] = np.nan
    write_npz(tmp_path / "nan.npz", compress=False, frames=bad, meta=np.array("{}"))
    with pytest.raises(ValueError, match="NaN or Inf .frame 2"):
        ClipFrames(tmp_path / "nan.npz")
    write_npz(tmp_path / "gray.npz", compress=False, frames=np.zeros((3, 4, 5), np.float16))
    with pytest.raises(ValueError, match=r"expected \[T,H,W,3\]"):
        ClipFrames(tmp_path / "gray.npz")
    write_npz(tmp_path / "other.npz", compress=False, pixels=np.zeros((3, 4, 5, 3), np.float16))
    with pytest.raises(ValueError, match="no 'frames' member"):
        ClipFrames(tmp_path / "other.npz")
    with pytest.raises(FileNotFoundError, match="clip not found"):
        ClipFrames(tmp_path / "missing.npz")
    buf = io.BytesIO()  # a header promising 6 frames before the data of 5
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f2", "fortran_order": False, "shape": (6, 4, 5, 3)})
    with zipfile.ZipFile(tmp_path / "cut.npz", "w") as zf:
        zf.writestr("frames.npy", buf.getvalue() + np.zeros((5, 4, 5, 3), np.float16).tobytes())
    with pytest.raises(ValueError, match="holds 600 bytes of data, its header promises"):
        ClipFrames(tmp_path / "cut.npz")


def test_training_views_hold_no_clip_in_memory(tmp_path):
    """Loading the targets of a round allocates about one frame, not V x T frames of float32 (the old
    load: every clip as float32, 40 frames x 3 views here)."""
    T, H, W = 40, 48, 64
    paths, cams = [], ring_cameras(3, W, H)
    for i in range(3):
        p = tmp_path / f"v{i}.npz"
        _random_clip(p, T, H, W, seed=i, camera=cams[i])
        paths.append(str(p))
    G, _ = sway_scene(n_dyn=10, grid=4)
    tracemalloc.start()
    views = training_views(G, paths, None, None, None, None, UpdateConfig(lambda_cano=0.0))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    frame = H * W * 3 * 4
    clips = 3 * T * frame
    print(f"training_views: traced peak {peak / 1e6:.2f} MB; the clips as float32 {clips / 1e6:.2f} MB")
    assert peak < 4 * frame < clips / 20
    assert all(isinstance(v.clip, ClipFrames) and v.clip.held_bytes == 0 for v in views)
    assert [v.camera.to_dict() for v in views] == [c.to_dict() for c in cams]  # from the clips' metadata


def test_update_on_frames_from_disk_equals_update_on_loaded_clips(tmp_path):
    """The same training, bit for bit, whether the targets are float32 tensors or read per step."""
    T = 7
    G, mask = sway_scene(n_dyn=30, grid=5)
    gt = sway_motion(G, mask, T, K=3, amplitude=0.08)
    loaded, lazy = [], []
    for i, c in enumerate(ring_cameras(2, 40, 30)):
        p = tmp_path / f"v{i}.npz"
        save_clip(p, render_clip(G, gt, c, T), {"camera": c.to_dict()})
        loaded.append(ViewData(c, torch.from_numpy(load_clip(p)[0])))
        lazy.append(ViewData(c, ClipFrames(p)))
    cfg = UpdateConfig(steps=6, views_per_step=2, num_bases=3, lambda_cano=0.1, seed=3)
    a = run_update(G, mask, loaded, cfg, progress=False)
    b = run_update(G, mask, lazy, cfg, progress=False)
    assert torch.equal(a.deformation.pos_coeffs, b.deformation.pos_coeffs)
    assert [h["loss"] for h in a.history] == [h["loss"] for h in b.history]
