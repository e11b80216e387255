"""TorchScript loading and the FVD/FID input protocol, with tiny scripted stand-in networks."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from anigs.metrics.features import (Unavailable, i3d_features, inception_features, load_detector, pool_frames,
                                    preprocess_fvd_clip, resize_center_crop, sample_windows)


class StandInI3D(torch.nn.Module):
    """Same call convention as the StyleGAN-V I3D TorchScript; returns a readable 'feature'.

    Feature = [T, H, W, min, max] + the input average-pooled to [3, 1, 2, 2] (12 values).
    """

    def forward(self, x: torch.Tensor, rescale: bool = False, resize: bool = False,
                return_features: bool = False) -> torch.Tensor:
        if rescale:
            x = x / 127.5 - 1.0
        if resize:
            x = F.interpolate(x, size=(x.shape[2], 224, 224), mode="trilinear", align_corners=False)
        b = x.shape[0]
        shape = torch.tensor([float(x.shape[2]), float(x.shape[3]), float(x.shape[4])]).expand(b, 3)
        mn = x.reshape(b, -1).min(dim=1).values[:, None]
        mx = x.reshape(b, -1).max(dim=1).values[:, None]
        h2, w2 = x.shape[3] // 2, x.shape[4] // 2
        pooled = x[:, :, :, :2 * h2, :2 * w2].reshape(b, 3, x.shape[2], 2, h2, 2, w2).double().mean(dim=(2, 4, 6))
        pooled = pooled.float().reshape(b, -1)
        out = torch.cat([shape, mn, mx, pooled], dim=1)
        if not return_features:
            out = out.softmax(dim=1)
        return out


class StandInInception(torch.nn.Module):
    """Same call convention as the StyleGAN2-ADA Inception TorchScript: [N,3,H,W] in [0,255]."""

    def forward(self, x: torch.Tensor, return_features: bool = False) -> torch.Tensor:
        n = x.shape[0]
        shape = torch.tensor([float(x.shape[2]), float(x.shape[3])]).expand(n, 2)
        return torch.cat([shape, x.reshape(n, -1).max(dim=1).values[:, None], x.mean(dim=(2, 3))], dim=1)


@pytest.fixture
def i3d_path(tmp_path):
    p = tmp_path / "i3d_torchscript.pt"
    torch.jit.script(StandInI3D()).save(str(p))
    return p


@pytest.fixture
def inception_path(tmp_path):
    p = tmp_path / "inception.pt"
    torch.jit.script(StandInInception()).save(str(p))
    return p


def test_load_detector_from_local_torchscript(i3d_path):
    det = load_detector(i3d_path, "FVD (I3D)")
    assert isinstance(det, torch.jit.ScriptModule)
    out = det(torch.zeros(1, 3, 10, 16, 16), rescale=False, resize=False, return_features=True)
    assert out.shape == (1, 17)


def test_missing_or_bad_weights_are_unavailable_not_crashes(tmp_path):
    missing = tmp_path / "nope" / "i3d_torchscript.pt"
    u = load_detector(missing, "FVD (I3D)", hint="get it from StyleGAN-V")
    assert isinstance(u, Unavailable)
    assert u.expected_path == str(missing) and "not found" in u.reason and "StyleGAN-V" in u.reason
    u = load_detector(None, "FVD (I3D)")
    assert isinstance(u, Unavailable) and "no weights path" in u.reason
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"definitely not torchscript")
    u = load_detector(junk, "FID")
    assert isinstance(u, Unavailable) and "not a loadable TorchScript" in u.reason
    assert u.to_dict()["expected_path"] == str(junk)


def test_resize_center_crop_keeps_aspect_and_centre():
    # 64x128 frame: columns 32..95 green, the rest red. Short side -> 256 gives 256x512;
    # the centre 256 columns are original columns 32..95: all green.
    frame = torch.zeros(1, 3, 64, 128)
    frame[:, 0] = 1
    frame[:, :, :, 32:96] = torch.tensor([0.0, 1.0, 0.0])[:, None, None]
    out = resize_center_crop(frame, 256)
    assert out.shape == (1, 3, 256, 256)
    inner = out[0, :, :, 8:-8]  # away from the antialiasing seam
    assert torch.allclose(inner[1], torch.ones_like(inner[1]), atol=1e-4)
    assert float(inner[0].abs().max()) < 1e-4
    # portrait frames crop vertically
    tall = torch.rand(2, 3, 300, 100)
    assert resize_center_crop(tall, 64).shape == (2, 3, 64, 64)


def test_fvd_protocol_through_scripted_network(i3d_path):
    det = load_detector(i3d_path, "FVD (I3D)")
    rng = np.random.default_rng(0)
    colour = np.array([0.2, 0.5, 0.8], np.float32)
    clips = [np.broadcast_to(colour, (6, 48, 80, 3)).copy(),  # short: padded to 10 frames
             rng.uniform(0, 1, (12, 60, 60, 3)).astype(np.float32)]
    feats, info = i3d_features(det, clips, crop_size=256, min_frames=10, batch_size=4, detector_resize=False)
    assert feats.shape == (2, 17) and feats.dtype == np.float64
    assert info["padded_frames"] == 4
    # the network saw [B,3,T,256,256] in [-1,1]
    assert feats[0, :3].tolist() == [10.0, 256.0, 256.0]
    assert feats[1, :3].tolist() == [12.0, 256.0, 256.0]
    assert feats[1, 3] >= -1.0 and feats[1, 4] <= 1.0
    # constant colour c maps to 2c - 1 in every pooled cell
    pooled = feats[0, 5:].reshape(3, 4)
    np.testing.assert_allclose(pooled, np.repeat(2 * colour[:, None] - 1, 4, axis=1), atol=1e-5)
    # detector_resize (default True) is forwarded to the network (it resizes to 224 inside)
    feats_r, _ = i3d_features(det, clips[:1], crop_size=256)
    assert feats_r[0, 1:3].tolist() == [224.0, 224.0]


def test_preprocess_fvd_clip_shapes_and_range():
    clip = np.random.default_rng(1).uniform(0, 1, (16, 40, 70, 3)).astype(np.float32)
    x, pad = preprocess_fvd_clip(clip, crop_size=32, min_frames=10)
    assert x.shape == (3, 16, 32, 32) and pad == 0
    assert float(x.min()) >= -1 and float(x.max()) <= 1
    with pytest.raises(ValueError, match=r"\[T,H,W,3\]"):
        preprocess_fvd_clip(clip[..., :2])


def test_fid_protocol_through_scripted_network(inception_path):
    det = load_detector(inception_path, "FID (Inception)")
    frames = [np.full((40, 60, 3), 0.5, np.float32)] * 3 + [np.ones((30, 30, 3), np.float32)]
    feats = inception_features(det, frames, size=299, batch_size=2)
    assert feats.shape == (4, 6)
    assert (feats[:, :2] == 299).all()  # resized to 299x299
    np.testing.assert_allclose(feats[:3, 3:], 127.5, atol=1e-3)  # [0,1] -> [0,255]
    np.testing.assert_allclose(feats[3, 2:], 255.0, atol=1e-3)


def test_sample_windows_and_pool_frames():
    clips = [np.zeros((20, 4, 4, 3), np.float32) + i for i in range(3)]
    wins = sample_windows(clips, frames=8, stride=4, max_clips=0)
    assert len(wins) == 3 * 4 and all(w.shape[0] == 8 for w in wins)  # starts 0,4,8,12
    few = sample_windows(clips, frames=8, stride=4, max_clips=5)
    assert len(few) == 5 and few[0][0, 0, 0, 0] == 0 and few[-1][0, 0, 0, 0] == 2
    whole = sample_windows(clips, frames=0, stride=4, max_clips=0)
    assert [w.shape[0] for w in whole] == [20, 20, 20]
    short = sample_windows([np.zeros((5, 2, 2, 3))], frames=8, stride=1, max_clips=10)
    assert len(short) == 1 and short[0].shape[0] == 5
    frames = pool_frames(clips, max_frames=7)
    assert len(frames) == 7 and frames[0].shape == (4, 4, 3)
    assert len(pool_frames(clips, 0)) == 60
