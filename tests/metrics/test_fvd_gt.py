"""FVD against the ground-truth motion: evaluation-only views, the reference and a method's record
(anigs.metrics.eval_views, anigs.metrics.fvd_gt, anigs.stages.fvd_gt), with a tiny random-weight I3D stand-in."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from anigs.metrics.eval_views import Placement, moving_labels, place_eval_views, window_starts
from anigs.metrics.config import EvalConfig
from anigs.metrics.fvd_gt import i3d_detector as REAL_DETECTOR
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.fvd_gt import FvdGtConfig, ReferenceOutputs

sys.path.insert(0, str(Path(__file__).parent))
from _tiny_i3d import TinyI3D  # noqa: E402

SMALL = {"num_views": 6, "width": 64, "height": 48, "bootstrap": 20, "frames": 8, "windows": 2}


@pytest.fixture(scope="module")
def gt_dir(tmp_path_factory):
    """A small synthetic garden's capture and ground truth (6 photos at 64x48, 3000 Gaussians)."""
    from anigs.synth import CameraPathConfig, SceneConfig, SynthConfig, write_capture

    out = tmp_path_factory.mktemp("capture")
    cfg = SynthConfig(0, SceneConfig(num_gaussians=3000), CameraPathConfig(num_images=6, width=64, height=48))
    write_capture(cfg, CaptureOutputs(out))
    return out / "gt"


def CAP(gt_dir):  # noqa: N802
    return CaptureOutputs(gt_dir.parent)


def _gt(gt_dir):
    from anigs.metrics.fvd_gt import _load_gt

    return _load_gt(CaptureOutputs(gt_dir.parent))


def test_window_starts():
    assert window_starts(25, 16, 2) == [0, 9]
    assert window_starts(16, 16, 1) == [0]
    with pytest.raises(ValueError, match="do not fit"):
        window_starts(10, 16, 1)
    with pytest.raises(ValueError, match="distinct"):
        window_starts(17, 16, 3)


def test_placement_is_deterministic_and_sees_the_moving_region(gt_dir):
    from anigs.render.labels import render_label_map

    gt, labels, _, motion, cams = _gt(gt_dir)
    spec = Placement(num_views=8, width=64, height=48, seed=3)
    a, rep = place_eval_views(gt, labels, moving_labels(motion), cams, spec)
    b, _ = place_eval_views(gt, labels, moving_labels(motion), cams, spec)
    assert [c.name for c in a] == [f"e{i:02d}" for i in range(8)]
    assert all(np.array_equal(x.viewmat, y.viewmat) for x, y in zip(a, b))
    c, _ = place_eval_views(gt, labels, moving_labels(motion), cams, Placement(num_views=8, width=64, height=48, seed=4))
    assert not np.array_equal(a[0].viewmat, c[0].viewmat)
    moving = moving_labels(motion)
    for cam in a:  # independently re-rendered: moving Gaussians dominate at least 10% of every view
        assert np.isin(render_label_map(gt, labels, cam), moving).mean() >= 0.10
    assert rep["dynamic_fraction_min"] >= 0.10
    # eyes stay near the capture path (the reconstruction is good there): within 4 jitter stds
    centres = np.stack([k.center for k in cams])
    assert max(np.linalg.norm(centres - cam.center, axis=1).min() for cam in a) < 4 * spec.jitter_m * 1.8


def test_placement_fails_clearly_when_nothing_moves(gt_dir):
    gt, labels, _, motion, cams = _gt(gt_dir)
    with pytest.raises(ValueError, match="nothing to look at"):
        place_eval_views(gt, labels, [99], cams, Placement(num_views=2))
    with pytest.raises(ValueError, match="only 0 of 2 views"):
        place_eval_views(gt, labels, moving_labels(motion), cams,
                         Placement(num_views=2, min_dynamic_fraction=1.01, max_tries_per_view=2))


def _gt_motion_model(gt_dir, out: Path, T: int, move: bool) -> Path:
    """model.pt whose DCT field reproduces the ground-truth motion exactly (K = T-1), or a still one."""
    from anigs.animate.deform import save_model
    from anigs.baselines.base import trajectories_to_deformation
    from anigs.metrics.eval_views import gt_offsets_at

    gt, labels, anchors, motion, _ = _gt(gt_dir)
    off = gt_offsets_at(gt, labels, anchors, motion, T)
    idx = torch.nonzero(off.abs().amax(dim=(0, 2)) > 0).squeeze(1) if move else torch.zeros(0, dtype=torch.long)
    traj = gt.means[idx][None].double() + off[:, idx].double()
    canon, deformation = trajectories_to_deformation(gt, idx, traj, T - 1)
    save_model(out, deformation, canon)
    return out


@pytest.fixture(scope="module")
def reference(gt_dir, tmp_path_factory, monkeypatch_module):
    from anigs.metrics import fvd_gt as F

    monkeypatch_module.setattr(F, "i3d_detector", lambda ecfg, dev: TinyI3D())
    out = tmp_path_factory.mktemp("ref")
    torch.set_num_threads(1)
    ref = F.run_reference(CaptureOutputs(gt_dir.parent), gt_dir / "cameras.json", gt_dir / "gaussians.ply", 25,
                          ReferenceOutputs(out),
                          FvdGtConfig.from_dict(SMALL), EvalConfig.from_dict({"fvd_crop_size": 64}))
    return out, ref


@pytest.fixture(scope="module")
def monkeypatch_module():
    mp = pytest.MonkeyPatch()
    yield mp
    mp.undo()


def test_reference_and_method_records(reference, gt_dir, tmp_path):
    from anigs.metrics import fvd_gt as F

    out, ref = reference
    assert ref["available"] and ref["clips"] == 12 and ref["views"] == 6 and ref["window_starts"] == [0, 17]
    assert (out / "views.png").exists() and (out / "features.npz").exists()
    still = ref["still_control"]
    assert still["available"] and still["samples"] == {"test": 12, "reference": 12, "views": 6}
    cfg, ecfg = FvdGtConfig.from_dict(SMALL), EvalConfig.from_dict({"fvd_crop_size": 64})
    exact = _gt_motion_model(gt_dir, tmp_path / "exact.pt", 25, move=True)
    rec, firsts = F.run_method(ReferenceOutputs(out), exact, gt_dir / "gaussians.ply", gt_dir / "cameras.json", CAP(gt_dir), cfg, ecfg)
    m = rec["fvd/gt"]
    assert m["available"] and len(firsts) == 6
    # the ground-truth motion itself, rendered through the methods' path: ~0, far below the still scene
    assert m["value"] < 1e-3 * still["value"] and still["value"] > 0
    assert m["bootstrap"]["resamples"] == 20 and m["samples"]["test"] == 12 and m["undersampled"]
    assert (out / "still_features.npz").exists() and m["gap_to_still"]["interval"][1] < 0  # motion beats no motion
    assert m["_features"].shape == (12, 400)
    still_model = _gt_motion_model(gt_dir, tmp_path / "still.pt", 25, move=False)
    rec2, _ = F.run_method(ReferenceOutputs(out), still_model, gt_dir / "gaussians.ply", gt_dir / "cameras.json", CAP(gt_dir), cfg, ecfg)
    # a still model through the methods' path gives the reference's still control, bit for bit
    assert rec2["fvd/gt"]["value"] == still["value"]
    assert rec2["fvd/gt"]["bootstrap"] == still["bootstrap"]
    assert rec2["fvd/gt"]["gap_to_still"]["mean"] == 0
    rec3, _ = F.run_method(ReferenceOutputs(out), still_model, gt_dir / "gaussians.ply", gt_dir / "cameras.json", CAP(gt_dir), cfg, ecfg)
    assert rec3["fvd/gt"]["value"] == rec2["fvd/gt"]["value"]  # same clips, same FVD, bit for bit


def test_method_with_other_views_is_refused(reference, gt_dir, tmp_path):
    from anigs.metrics import fvd_gt as F

    out, _ = reference
    model = _gt_motion_model(gt_dir, tmp_path / "m.pt", 25, move=False)
    with pytest.raises(ValueError, match="other views"):
        F.run_method(ReferenceOutputs(out), model, gt_dir / "gaussians.ply", gt_dir / "cameras.json", CAP(gt_dir),
                     FvdGtConfig.from_dict(dict(SMALL, num_views=7)), EvalConfig.from_dict({}))


def test_nan_render_is_an_error_naming_the_clip(reference, gt_dir):
    from anigs.metrics import fvd_gt as F

    cams = _gt(gt_dir)[4][:2]
    bad = lambda cam: np.full((25, 48, 64, 3), np.nan, np.float32)  # noqa: E731
    with pytest.raises(ValueError, match=r"clip 'method img_000"):
        F._feature_loop("method", cams, bad, [0], FvdGtConfig.from_dict(SMALL), EvalConfig.from_dict({}),
                        TinyI3D(), "cpu")


def test_missing_network_is_not_available(gt_dir, tmp_path, monkeypatch):
    from anigs.metrics import fvd_gt as F

    monkeypatch.setattr(F, "i3d_detector", REAL_DETECTOR)

    ref = F.run_reference(CaptureOutputs(gt_dir.parent), gt_dir / "cameras.json", gt_dir / "gaussians.ply", 25,
                          ReferenceOutputs(tmp_path),
                          FvdGtConfig.from_dict(dict(SMALL, num_views=2)),
                          EvalConfig.from_dict({"i3d_path": str(tmp_path / "none.pt")}))
    assert not ref["available"] and "none.pt" in ref["reason"]
    model = _gt_motion_model(gt_dir, tmp_path / "m.pt", 25, move=False)
    rec, _ = F.run_method(ReferenceOutputs(tmp_path), model, gt_dir / "gaussians.ply", gt_dir / "cameras.json",
                          CAP(gt_dir),
                          FvdGtConfig.from_dict(dict(SMALL, num_views=2)), EvalConfig.from_dict({}))
    assert not rec["fvd/gt"]["available"] and "none.pt" in rec["fvd/gt"]["reason"]


def test_config_checks():
    with pytest.raises(ValueError, match="when"):
        FvdGtConfig.from_dict({"when": "sometimes"})
    with pytest.raises(ValueError):
        FvdGtConfig.from_dict({"num_views": 1})
