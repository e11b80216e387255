"""Model update: recovery of a known motion, parameter groups, hard cases, NaN guard, CLI."""
from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest
import torch

from anigs.animate.frames import render_clip, render_frame
from anigs.animate.deform import DCTDeformation, load_model
from anigs.animate.losses import SDSContext, largest_4m1, photometric_loss, prior_sds_hook
from anigs.animate.update import UpdateDiverged, ViewData, run_update
from anigs.animate.config import UpdateConfig
from tests._scenes import ring_cameras, sway_motion, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")



def make_views(G, gt, cams, T):
    out = []
    for c in cams:
        clip = render_clip(G, gt, c, T)
        out.append(ViewData(c, clip, clip[0]))
    return out


def trajectory_errors(gt, G, deformation, canonical, T):
    ts = torch.arange(T, dtype=torch.float64)
    with torch.no_grad():
        p_gt = gt.trajectories(G.means, ts)
        p = deformation.trajectories(canonical.means, ts)
        disp = (p_gt - G.means[gt.dynamic_index]).norm(dim=-1)
        rmse = (p - p_gt).norm(dim=-1).pow(2).mean().sqrt()
    return float(rmse), float(disp.pow(2).mean().sqrt()), float(disp.max())


# ---- the key proof ----------------------------------------------------------------------
def test_update_recovers_a_known_multiview_motion():
    """Render camera-fixed clips of a swaying shrub from 4 views, fit from zero coefficients,
    recover the 3D trajectories: RMSE < 10% of the RMS displacement (stricter than 10% of the
    peak amplitude); static Gaussians unmoved."""
    T = 13
    G, mask = sway_scene()
    gt = sway_motion(G, mask, T, K=4, amplitude=0.08)
    views = make_views(G, gt, ring_cameras(4, 96, 72), T)
    cfg = UpdateConfig(steps=250, views_per_step=2, num_bases=4, rotation=False, lambda_cano=0.1,
                       lr_position_coeffs=2e-3, seed=0)
    zero = DCTDeformation(gt.dynamic_index, T, 4, rotation=False, num_gaussians=G.num)
    rmse0, rms_disp, peak = trajectory_errors(gt, G, zero, G, T)
    assert rmse0 > 0.9 * rms_disp  # the starting point is wrong by the whole motion
    res = run_update(G, mask, views, cfg, progress=False)
    rmse, rms_disp, peak = trajectory_errors(gt, G, res.deformation, res.canonical, T)
    print(f"recovery: RMSE {rmse:.5f}, RMS displacement {rms_disp:.4f} ({rmse / rms_disp:.1%}), "
          f"peak {peak:.4f} ({rmse / peak:.1%})")
    assert rmse < 0.1 * rms_disp
    static = ~mask
    assert torch.equal(res.canonical.means[static], G.means[static])
    for t in (0, 5, 12):
        g = res.deformation(res.canonical, t)
        assert torch.equal(g.means[static], G.means[static]) and torch.equal(g.quats, G.quats)
    assert res.history[-1]["loss"] < 0.5 * res.history[0]["loss"]


# ---- parameter groups and determinism --------------------------------------------------------
def _small_problem(T=9, n_dyn=40, size=(48, 36), views=2):
    G, mask = sway_scene(n_dyn=n_dyn, grid=6, anisotropic=True)
    gt = sway_motion(G, mask, T, K=3, amplitude=0.08)
    return G, mask, make_views(G, gt, ring_cameras(views, *size), T)


@pytest.mark.parametrize("group", ["deformation", "deformation+positions", "all"])
def test_parameter_groups(group):
    G, mask, views = _small_problem()
    res = run_update(G, mask, views, UpdateConfig(steps=4, num_bases=3, param_groups=group), progress=False)
    static, dyn = ~mask, mask
    assert res.deformation.pos_coeffs.abs().max() > 0 and res.deformation.rot_coeffs.abs().max() > 0
    if group == "deformation":
        assert torch.equal(res.canonical.means, G.means)
    if group == "deformation+positions":
        assert torch.equal(res.canonical.means[static], G.means[static])
        assert not torch.equal(res.canonical.means[dyn], G.means[dyn])
    if group != "all":
        for k in ("quats", "log_scales", "opacity_logits", "sh"):
            assert torch.equal(getattr(res.canonical, k), getattr(G, k)), k
    else:
        assert not torch.equal(res.canonical.sh, G.sh) and not torch.equal(res.canonical.means[static], G.means[static])


def test_update_is_deterministic_for_a_seed():
    G, mask, views = _small_problem()
    cfg = UpdateConfig(steps=5, num_bases=3, seed=3)
    a = run_update(G, mask, views, cfg, progress=False)
    b = run_update(G, mask, views, cfg, progress=False)
    c = run_update(G, mask, views, UpdateConfig(steps=5, num_bases=3, seed=4), progress=False)
    assert torch.equal(a.deformation.pos_coeffs, b.deformation.pos_coeffs)
    assert torch.equal(a.canonical.means, b.canonical.means)
    assert not torch.equal(a.deformation.pos_coeffs, c.deformation.pos_coeffs)


@pytest.mark.parametrize("bad, error, match", [
    ({"lamda_cano": 1.0}, KeyError, "lamda_cano"),
    ({"param_groups": "positions"}, ValueError, "param_groups"),
    ({"sds_frames": 8}, ValueError, "4m\\+1"),
    ({"effect_limits": {"1": {"max_offset": 0.1}}}, KeyError, "max_offset"),
])
def test_config_rejects_unknown_and_bad_values(bad, error, match):
    with pytest.raises(error, match=match):
        UpdateConfig.from_dict(bad)
    assert UpdateConfig.from_dict({"steps": 3}).steps == 3


# ---- hard cases --------------------------------------------------------------------------------
def test_empty_dynamic_set_is_a_logged_noop(caplog):
    G, mask, views = _small_problem()
    with caplog.at_level(logging.INFO, logger="anigs.animate.update"):
        res = run_update(G, torch.zeros(G.num, dtype=torch.bool), views, UpdateConfig(steps=50), progress=False)
    assert "dynamic set is empty" in caplog.text and res.skipped and res.steps == 0
    assert res.deformation.num_dynamic == 0
    assert torch.equal(res.canonical.means, G.means)
    assert torch.equal(render_frame(G, res.deformation, views[0].camera, 4), render_frame(G, None, views[0].camera, 0))


def test_single_frame_targets_and_k_clamped(caplog):
    G, mask, views = _small_problem(T=1)
    with caplog.at_level(logging.INFO, logger="anigs.animate.update"):
        res = run_update(G, mask, views, UpdateConfig(steps=10, num_bases=16), progress=False)
    assert "clamped to K=0" in caplog.text and "no-op" in caplog.text
    assert res.deformation.num_bases == 0
    G2, mask2, views2 = _small_problem(T=5)
    with caplog.at_level(logging.WARNING, logger="anigs.animate.update"):
        res = run_update(G2, mask2, views2, UpdateConfig(steps=2, num_bases=16), progress=False)
    assert res.deformation.num_bases == 4 and "clamped to K=4" in caplog.text


def test_amplitude_limits_hold_during_training():
    G, mask, views = _small_problem()
    cfg = UpdateConfig(steps=15, num_bases=3, lr_position_coeffs=0.5, max_offset_frac=0.02, max_angle_deg=2.0,
                       effect_limits={"2": {"max_offset_frac": 0.05}})
    res = run_update(G, mask, views, cfg, progress=False)
    h = G.means[mask, 2]
    for t in range(9):
        dmu, dq = res.deformation.offsets(t)
        assert bool((dmu.norm(dim=1) <= 0.02 * h * (1 + 1e-4)).all())
        assert bool((2 * torch.atan2(dq[:, 1:].norm(dim=1), dq[:, 0].abs()) <= math.radians(2.0) + 1e-5).all())
    labels = mask.long()
    labels[mask.nonzero()[:5, 0]] = 2  # per-effect override
    res2 = run_update(G, labels, views, cfg, progress=False)
    assert torch.allclose(res2.deformation.max_offset[:5], 0.05 * h[:5])
    assert torch.allclose(res2.deformation.max_offset[5:], 0.02 * h[5:])


def test_nan_loss_stops_with_iteration_and_saves_last_good_state(tmp_path):
    G, mask, views = _small_problem()

    def sds(ctx: SDSContext) -> torch.Tensor:
        clip = ctx.render_subclip(0, 0, 5, grad_frame=2)
        return clip.mean() * (float("nan") if ctx.step == 4 else 1.0)

    path = tmp_path / "model.last_good.pt"
    cfg = dict(num_bases=3, lambda_sds=0.1, lr_final_factor=1.0)
    with pytest.raises(UpdateDiverged, match="iteration 4") as err:
        run_update(G, mask, views, UpdateConfig(steps=10, **cfg), sds_fn=sds, failure_path=path, progress=False)
    assert err.value.iteration == 4 and err.value.saved_path == path
    canon, d, payload = load_model(path, G)
    assert payload["extra"]["iteration"] == 4 and d.pos_coeffs.abs().max() > 0
    # the saved state is the one after the 3 good steps: identical to a 3-step run
    ref = run_update(G, mask, views, UpdateConfig(steps=3, **cfg), sds_fn=sds, progress=False)
    assert torch.equal(d.pos_coeffs, ref.deformation.pos_coeffs)
    assert torch.equal(canon.means, ref.canonical.means)


def test_nan_gradient_is_detected(tmp_path):
    G, mask, views = _small_problem()

    def sds(ctx: SDSContext) -> torch.Tensor:
        x = ctx.render_subclip(1, 2, 1, grad_frame=0).mean()
        return torch.sqrt(x - x) if ctx.step == 2 else x  # finite value 0, NaN gradient (d sqrt at 0)

    with pytest.raises(UpdateDiverged, match="iteration 2: non-finite gradient"):
        run_update(G, mask, views, UpdateConfig(steps=5, num_bases=3, lambda_sds=1.0), sds_fn=sds,
                   failure_path=tmp_path / "f.pt", progress=False)
    assert (tmp_path / "f.pt").exists()


def test_sds_hook_gets_gradients_through_one_frame_only():
    G, mask, views = _small_problem()
    seen = {}

    class FakePrior:
        name, has_score = "fake", True

        def __init__(self, use_grad_frame: bool):
            self.use_grad_frame = use_grad_frame

        def sds_loss(self, clip, prompt, generator, grad_frame=None):
            seen.update(n=clip.shape[0], j=grad_frame, prompt=prompt)
            keep = torch.arange(clip.shape[0]) == grad_frame
            sel = clip[keep] if self.use_grad_frame else clip[~keep]
            return ((sel - 0.3) ** 2).mean()

    cfg = UpdateConfig(steps=1, num_bases=3, lambda_sds=100.0, lambda_cano=0.0)
    base = run_update(G, mask, views, UpdateConfig(steps=1, num_bases=3, lambda_cano=0.0), progress=False)
    others = run_update(G, mask, views, cfg, sds_fn=prior_sds_hook(FakePrior(False), "wind", 9), progress=False)
    assert seen["n"] == 9 and seen["prompt"] == "wind" and others.history[0]["l_sds"] > 0
    # the frames rendered without gradient change nothing
    assert torch.equal(others.deformation.pos_coeffs, base.deformation.pos_coeffs)
    one = run_update(G, mask, views, cfg, sds_fn=prior_sds_hook(FakePrior(True), "wind", 9), progress=False)
    assert not torch.equal(one.deformation.pos_coeffs, base.deformation.pos_coeffs)
    assert largest_4m1(13) == 13 and largest_4m1(12) == 9 and largest_4m1(1) == 1

    class NoScore:
        name, has_score = "procedural", False

    with pytest.raises(ValueError, match="no score"):
        prior_sds_hook(NoScore())


def test_photometric_loss_is_zero_for_identical_images():
    a = torch.rand(2, 16, 16, 3, generator=torch.Generator().manual_seed(0))
    assert float(photometric_loss(a, a)) == pytest.approx(0.0, abs=1e-6)
    assert float(photometric_loss(a, a.flip(1))) > 0.05


# ---- CLI ----------------------------------------------------------------------------------------------
def test_cli_render_clip_and_update_round_trip(tmp_path):
    from anigs.cli import main
    from anigs.video import load_clip, save_clip

    T = 9
    G, mask = sway_scene(n_dyn=40, grid=6)
    gt = sway_motion(G, mask, T, K=3, amplitude=0.08)
    ply = tmp_path / "static" / "canonical.ply"
    G.save_ply(ply)
    (tmp_path / "masks").mkdir()
    np.save(tmp_path / "masks" / "dynamic.npy", mask.numpy())
    cams = ring_cameras(2, 48, 36)
    views = [{"id": f"v{i}", "camera": c.to_dict()} for i, c in enumerate(cams)]
    (tmp_path / "views").mkdir()
    (tmp_path / "views" / "views.json").write_text(json.dumps({"views": views}))
    (tmp_path / "cam0.json").write_text(json.dumps(cams[0].to_dict()))
    params = json.dumps({"num_frames": T})
    static, masks, vdir = str(tmp_path / "static"), str(tmp_path / "masks"), str(tmp_path / "views")

    # round 0: no model -> every frame is the static canonical render
    r0 = tmp_path / "round0" / "render" / "v0.npz"
    assert main(["render_clip", "--static", static, "--camera-json", str(tmp_path / "cam0.json"), "--view-id", "v0",
                 "--out", str(tmp_path / "round0"), "--params", params]) == 0
    clip0, meta0 = load_clip(r0)
    assert clip0.shape == (T, 36, 48, 3) and all(np.array_equal(clip0[0], f) for f in clip0)
    assert meta0["camera"]["width"] == 48 and meta0["model"] is None

    targets = []
    for i, c in enumerate(cams):
        p = tmp_path / "round1" / "target" / f"v{i}.npz"
        save_clip(p, render_clip(G, gt, c, T), {"camera": c.to_dict()})
        targets.append(str(p))
    out = tmp_path / "round1" / "model.pt"
    upd = json.dumps({"steps": 3, "num_bases": 3, "views_per_step": 1, "contain": False})
    assert main(["update", "--static", static, "--targets", *targets, "--views", vdir, "--masks", masks,
                 "--out", str(tmp_path / "round1"), "--params", upd]) == 0
    canon, d, payload = load_model(out, ply)
    assert d.num_dynamic == int(mask.sum()) and (d.num_frames, d.num_bases) == (T, 3)
    assert json.loads((tmp_path / "round1" / "update.json").read_text())["steps"] == 3
    assert payload["extra"]["init_model"] is None

    # round 2: init from round 1, cameras from the targets' metadata
    out2 = tmp_path / "round2" / "model.pt"
    assert main(["update", "--static", static, "--init", str(tmp_path / "round1"), "--targets", *targets,
                 "--masks", masks, "--out", str(tmp_path / "round2"), "--params", upd]) == 0
    assert load_model(out2, ply)[2]["extra"]["init_model"] == str(out)
    r2 = tmp_path / "round2" / "render" / "v1.npz"
    assert main(["render_clip", "--static", static, "--model", str(tmp_path / "round2"), "--views", vdir,
                 "--view-id", "v1", "--out", str(tmp_path / "round2"), "--params", params]) == 0
    clip2, meta2 = load_clip(r2)
    assert clip2.shape == (T, 36, 48, 3) and not np.array_equal(clip2[0], clip2[T // 2])
    assert meta2["view_id"] == "v1" and meta2["model"] == str(out2)

    # a baseline variant's update job fits the baseline instead (same inputs, same model.pt format)
    out_b = tmp_path / "baseline" / "model.pt"
    assert main(["update", "--static", static, "--targets", *targets, "--views", vdir, "--masks", masks,
                 "--out", str(tmp_path / "baseline"), "--params", upd,
                 "--method", "lifting", "--method-params", json.dumps({"num_bases": 3})]) == 0
    _, db, _ = load_model(out_b, ply)
    assert db.num_dynamic == int(mask.sum()) and db.num_bases == 3 and db.pos_coeffs.abs().sum() > 0

    # clear errors: unknown view id, unknown config key, frame-count mismatch
    assert main(["render_clip", "--static", static, "--views", vdir, "--view-id", "nope", "--out",
                 str(tmp_path / "x"), "--params", params]) == 1
    assert main(["update", "--static", static, "--targets", *targets, "--masks", masks,
                 "--out", str(tmp_path / "y"), "--params", json.dumps({"stepz": 1})]) == 1
    assert main(["render_clip", "--static", static, "--model", str(tmp_path / "round2"), "--camera-json",
                 str(tmp_path / "cam0.json"), "--out", str(tmp_path / "z"), "--params", '{"num_frames": 5}']) == 1
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists() and not (tmp_path / "z").exists()
