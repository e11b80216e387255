"""Static 3DGS fit: initialisation, hard cases (1 point, duplicates, all pruned, NaN), end-to-end fit, CLI."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
from anigs.static.densify import AllPrunedError
from anigs.geometry.extent import scene_extent
from anigs.static.fit import StaticConfig, FitDivergedError, fit_static, init_gaussians, split_holdout
from anigs.gaussians import Gaussians, load_ply

pytestmark = pytest.mark.usefixtures("one_thread")


def _texture(p: np.ndarray) -> np.ndarray:
    u, v, w = p[:, 0], p[:, 1], p[:, 2]
    return np.clip(np.stack([0.5 + 0.35 * np.sin(4 * u + 2 * w), 0.5 + 0.35 * np.cos(5 * v - 3 * w),
                             0.45 + 0.3 * np.sin(3 * (u + v) + 1)], 1), 0, 1)


def make_scene(n_cams: int = 16, width: int = 64, height: int = 48, spacing: float = 0.12, seed: int = 0):
    """Ground-truth Gaussians (a textured ground and wall of flat splats), cameras on a ring, images."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(-1.5, 1.5, spacing), np.arange(-1.5, 1.5, spacing))
    ground = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)]
    wx, wz = np.meshgrid(np.arange(-1.5, 1.5, spacing), np.arange(0.0, 1.2, spacing))
    wall = np.c_[wx.ravel(), np.full(wx.size, 1.0), wz.ravel()]
    pts = np.concatenate([ground, wall]) + rng.normal(0, 0.01, (len(ground) + len(wall), 3))
    n = len(pts)
    scales = np.full((n, 3), spacing * 0.7)
    scales[: len(ground), 2] = 0.01
    scales[len(ground):, 1] = 0.01
    g = Gaussians.from_points(torch.tensor(pts).float(), torch.tensor(_texture(pts)).float(),
                              torch.tensor(scales).float(), opacity=0.95)
    K = intrinsics_from_fov(70, width, height)
    cams = []
    for i in range(n_cams):
        a = -math.pi * 0.9 + 1.8 * math.pi * i / n_cams  # an arc in front of the wall
        eye = (3.0 * math.cos(a), -0.3 + 3.0 * math.sin(a) * 0.6 - 1.2, 1.3 + 0.2 * math.sin(2 * a))
        cams.append(Camera(K, look_at(eye, (0, 0.2, 0.3)), width, height, f"img_{i:03d}.png"))
    from anigs.render import render_gaussians

    with torch.no_grad():
        imgs = [render_gaussians(g, c)[0].clamp(0, 1) for c in cams]
    return g, cams, imgs


def sfm_points(g: Gaussians, every: int = 3, noise: float = 0.03, seed: int = 1):
    """Pseudo-SfM: every ``every``-th GT mean plus noise, with the GT colour."""
    rng = np.random.default_rng(seed)
    p = g.means.numpy()[::every]
    return p + rng.normal(0, noise, p.shape), g.rgb.numpy()[::every]


FAST = {"iterations": 40, "eval_every": 20, "checkpoint_every": 10, "sh_increase_every": 10,
        "densify": {"start": 10, "stop": 30, "every": 10, "reset_every": 0}}


@pytest.fixture(scope="module")
def scene():
    return make_scene()


# ---------------------------------------------------------------------------- config and helpers
def test_config_rejects_unknown_keys_and_bad_values():
    with pytest.raises(ValueError, match="iteratons"):
        StaticConfig.from_dict({"iteratons": 3})
    with pytest.raises(ValueError, match="max_gausians"):
        StaticConfig.from_dict({"densify": {"max_gausians": 3}})
    with pytest.raises(ValueError, match="sh_degree"):
        StaticConfig.from_dict({"sh_degree": 4})
    cfg = StaticConfig.from_dict({"background": [1, 1, 1], "densify": {"max_gaussians": 10}})
    assert cfg.background == (1.0, 1.0, 1.0) and cfg.densify.max_gaussians == 10


def test_holdout_every_eighth():
    train, test = split_holdout(20, 8)
    assert test == [0, 8, 16]
    assert sorted(train + test) == list(range(20))
    assert split_holdout(5, 0) == ([0, 1, 2, 3, 4], [])
    with pytest.raises(ValueError, match="no training images"):
        split_holdout(1, 8)


def test_init_scale_from_three_nearest_neighbours():
    gx, gy = np.meshgrid(np.arange(10) * 0.2, np.arange(10) * 0.2)
    pts = np.c_[gx.ravel(), gy.ravel(), np.zeros(100)]
    g = init_gaussians(pts, np.full((100, 3), 0.3), extent=5.0)
    assert g.num == 100 and g.sh_degree == 3
    # interior points of a grid: the three nearest neighbours are all at the spacing
    inner = (np.abs(pts[:, 0] - 0.9) < 0.5) & (np.abs(pts[:, 1] - 0.9) < 0.5)
    assert torch.allclose(g.scales[torch.from_numpy(inner)], torch.tensor(0.2), atol=1e-5)
    assert torch.allclose(g.rgb, torch.tensor(0.3), atol=1e-5)


def test_init_single_point_and_duplicates():
    g1 = init_gaussians(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]), extent=2.0)
    assert g1.num == 1 and torch.allclose(g1.scales, torch.tensor(0.02))
    pts = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [1, 0, 0.0]])
    cols = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    g = init_gaussians(pts, cols, extent=2.0)
    assert g.num == 2  # duplicates merged
    assert torch.isfinite(g.log_scales).all() and (g.scales > 0).all()
    assert torch.allclose(g.rgb[0], torch.tensor([1 / 3, 1 / 3, 1 / 3]), atol=1e-5)
    gd = init_gaussians(np.zeros((5, 3)), np.full((5, 3), 0.5), extent=2.0)  # all identical
    assert gd.num == 1 and torch.isfinite(gd.log_scales).all()
    with pytest.raises(ValueError, match="empty"):
        init_gaussians(np.zeros((0, 3)), np.zeros((0, 3)), extent=1.0)


def test_scene_extent_from_cameras(scene):
    _, cams, _ = scene
    centers = np.stack([c.center for c in cams])
    r = np.linalg.norm(centers - centers.mean(0), axis=1).max()
    assert scene_extent(cams) == pytest.approx(1.1 * r)


# ---------------------------------------------------------------------------- hard cases
def test_fit_from_a_single_point(scene):
    _, cams, imgs = scene
    g, m = fit_static(imgs, cams, np.array([[0.0, 0.0, 0.3]]), np.array([[0.5, 0.5, 0.5]]),
                      StaticConfig.from_dict({**FAST, "far_share": 0.0}), progress=False)  # no far points: one start
    assert m["init_gaussians"] == 1
    assert g.num >= 1 and torch.isfinite(g.means).all()
    assert math.isfinite(m["test_psnr"])


def test_fit_from_duplicate_points(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=6)
    p = np.concatenate([p, p, p[:10]])
    c = np.concatenate([c, c, c[:10]])
    g, m = fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=True)  # the tqdm path too
    assert m["init_gaussians"] - m["far_points"] == len(p) // 2 - 5  # duplicates merged
    g.check_finite()


def test_all_pruned_stops_with_clear_error(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=6)
    cfg = StaticConfig.from_dict({**FAST, "init_opacity": 0.01, "lr_opacity": 0.0,
                               "densify": {"start": 5, "every": 5, "prune_opacity": 0.5, "reset_every": 0}})
    with pytest.raises(AllPrunedError, match=r"all \d+ Gaussians would be pruned at step 5"):
        fit_static(imgs, cams, p, c, cfg, progress=False)


def _nan_loss_from(monkeypatch, nan_at) -> dict:
    """Patch the fit's loss to NaN on the calls ``n`` (1-based) where ``nan_at(n)``; the call count."""
    import anigs.static.fit as fit_mod

    real_loss = fit_mod.loss_fn
    calls = {"n": 0}

    def loss(pred, target, w):
        calls["n"] += 1
        out = real_loss(pred, target, w)
        return out * float("nan") if nan_at(calls["n"]) else out

    monkeypatch.setattr(fit_mod, "loss_fn", loss)
    return calls


def test_nan_loss_is_detected_and_last_checkpoint_kept(scene, tmp_path, monkeypatch):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=6)
    _nan_loss_from(monkeypatch, lambda n: n >= 25)
    ckpt = tmp_path / "ckpt" / "last.ply"
    with pytest.raises(FitDivergedError, match=r"iteration 25: loss is nan.*iteration 20\).*last\.ply"):
        fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=False, checkpoint_path=ckpt)
    kept = load_ply(ckpt)
    kept.check_finite()
    assert kept.num > 0
    assert not any(f.name.startswith(".") for f in ckpt.parent.iterdir())  # no temp files left


def test_nan_gradient_is_detected(scene, monkeypatch):
    import anigs.static.fit as fit_mod

    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=6)
    real_loss = fit_mod.loss_fn

    class _NanGrad(torch.autograd.Function):
        @staticmethod
        def forward(ctx, x):
            return x.clone()

        @staticmethod
        def backward(ctx, g):
            return g * float("nan")

    monkeypatch.setattr(fit_mod, "loss_fn", lambda a, b, w: real_loss(_NanGrad.apply(a), b, w))
    with pytest.raises(FitDivergedError, match=r"iteration 1: non-finite gradient"):
        fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=False)


# ---------------------------------------------------------------------------- end to end
def test_fit_end_to_end_improves_held_out_psnr(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=3, noise=0.03)
    # the scene is rendered onto black: a synthetic scene's background is known (as the demo's sky)
    cfg = StaticConfig.from_dict({"iterations": 300, "eval_every": 100, "sh_degree": 1, "sh_increase_every": 150,
                               "background": [0.0, 0.0, 0.0],
                               "densify": {"start": 50, "stop": 250, "every": 50, "reset_every": 0,
                                           "max_gaussians": 3000}})
    g, m = fit_static(imgs, cams, p, c, cfg, progress=False)
    assert m["test_views"] == 2 and m["train_views"] == 14
    assert m["test_psnr"] > m["init_test_psnr"] + 6, m["curve"]
    assert m["test_psnr"] > 24.0, m["curve"]
    assert m["train_psnr"] > 24.0
    assert [r["iteration"] for r in m["curve"]] == [0, 100, 200, 300]
    assert g.sh_degree == 1 and m["num_gaussians"] == g.num


def test_fit_is_deterministic(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    cfg = StaticConfig.from_dict({**FAST, "densify": {"start": 5, "stop": 30, "every": 5, "grad_threshold": 0.00005,
                                                   "reset_every": 20}})
    g1, m1 = fit_static(imgs, cams, p, c, cfg, progress=False)
    g2, m2 = fit_static(imgs, cams, p, c, cfg, progress=False)
    assert m1["num_gaussians"] > m1["init_gaussians"]  # densification ran
    for k, v in g1.params().items():
        assert torch.equal(v, g2.params()[k]), k
    assert m1["test_psnr"] == m2["test_psnr"]


def test_cli_writes_ply_and_metrics(scene, tmp_path, capsys):
    from anigs.cli import main
    from anigs.io import write_npz
    from anigs.video import save_png

    gt, cams, imgs = scene
    img_dir = tmp_path / "images"
    for cam, im in zip(cams, imgs):
        save_png(img_dir / cam.name, im.numpy())
    save_cameras(tmp_path / "cameras.json", cams)
    p, c = sfm_points(gt, every=4)
    write_npz(tmp_path / "points.npz", xyz=p.astype(np.float32), rgb=c.astype(np.float32))
    out = tmp_path / "static"
    # --plan-only: the plan printed, nothing fitted or written (no --out needed)
    rc = main(["static", "--images", str(img_dir), "--cameras", str(tmp_path / "cameras.json"),
               "--points", str(tmp_path / "points.npz"), "--plan-only", "--params", json.dumps(FAST)])
    printed = capsys.readouterr().out
    assert rc == 0 and "static fit plan (budget auto; set: iterations, densify.stop)" in printed
    assert json.loads(printed[printed.index("{"):])["iterations"] == 40 and not out.exists()
    rc = main(["static", "--images", str(img_dir), "--cameras", str(tmp_path / "cameras.json"),
               "--points", str(tmp_path / "points.npz"), "--out", str(out), "--no-progress",
               "--params", json.dumps({**FAST, "sh_degree": 2})])
    assert rc == 0
    g = load_ply(out / "canonical.ply")
    assert g.sh_degree == 2
    m = json.loads((out / "metrics.json").read_text())
    for key in ("train_psnr", "train_ssim", "test_psnr", "test_ssim", "num_gaussians", "iterations", "seconds",
                "curve"):
        assert key in m, key
    assert m["num_gaussians"] == g.num and m["iterations"] == 40
    assert [r["iteration"] for r in m["curve"]] == [0, 20, 40]
    assert all("train_seconds" in r and "test_psnr" in r for r in m["curve"])
    assert not (out / "checkpoint.ply").exists()
    # a camera without an image is a clear error naming it
    save_cameras(tmp_path / "more.json", cams + [Camera(cams[0].K, cams[0].viewmat, 64, 48, "missing.png")])
    rc = main(["static", "--images", str(img_dir), "--cameras", str(tmp_path / "more.json"),
               "--points", str(tmp_path / "points.npz"), "--out", str(out), "--no-progress"])
    assert rc == 1


def test_load_points_formats(tmp_path):
    from anigs.sfm.model import load_points

    np.savez(tmp_path / "a.npz", points=np.zeros((4, 3)), colors=np.full((4, 3), 255, np.uint8))
    p, c = load_points(tmp_path / "a.npz")
    assert p.shape == (4, 3) and np.allclose(c, 1.0)
    np.savez(tmp_path / "b.npz", rgb=np.zeros((4, 3)))
    with pytest.raises(KeyError, match="'xyz' or 'points'"):
        load_points(tmp_path / "b.npz")
    with pytest.raises(FileNotFoundError, match="anigs sfm"):
        load_points(tmp_path / "missing.npz")


def test_fit_ends_densification_before_its_last_steps(scene, monkeypatch):
    """densify.stop beyond the fit's length is cut to stop_fraction x iterations."""
    import anigs.static.fit

    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    seen = []
    real = anigs.static.fit.refine

    def spy(params, optimizer, state, step, cfg, *a, **k):
        seen.append(cfg.stop)
        return real(params, optimizer, state, step, cfg, *a, **k)

    monkeypatch.setattr(anigs.static.fit, "refine", spy)
    cfg = StaticConfig.from_dict({**FAST, "densify": {"start": 10, "stop": 1000, "every": 10, "reset_every": 0}})
    fit_static(imgs, cams, p, c, cfg, progress=False)
    assert seen and set(seen) == {32}  # 0.8 x 40 iterations


# ---------------------------------------------------------------------------- the step
def test_nan_loss_is_detected_with_a_non_fused_optimizer(scene, monkeypatch):
    """Without a fused Adam (no found_inf skip) the divergence record is read every step."""
    import anigs.static.fit as fit_mod

    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=6)
    calls = _nan_loss_from(monkeypatch, lambda n: n == 7)

    def foreach_adam(params, lr):
        return torch.optim.Adam([{"params": [params[k]], "lr": lr[k], "name": k} for k in params], lr=0.0,
                                eps=1e-15, foreach=True)

    monkeypatch.setattr(fit_mod, "make_optimizer", foreach_adam)
    with pytest.raises(FitDivergedError, match=r"iteration 7: loss is nan"):
        fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=False)
    assert calls["n"] == 7  # stopped at once


def test_a_non_finite_step_is_skipped_until_reported(scene, monkeypatch):
    """With the fused Adam a non-finite step leaves the parameters as they were."""
    import anigs.static.fit as fit_mod
    from anigs.static.fit import DivergenceGuard, to_params, make_optimizer, train_step

    gt, cams, imgs = scene
    g = gt.with_sh_degree(1)
    g = Gaussians(g.means.clone(), g.quats.clone(), g.log_scales.clone(), g.opacity_logits.clone(), g.sh)
    params = to_params(g, torch.device("cpu"))  # (trained in place: not the fixture's tensors)
    opt = make_optimizer(params, {k: 1e-3 for k in params})
    assert opt.defaults["fused"]
    guard = DivergenceGuard(opt, list(params), torch.device("cpu"))
    bg = torch.zeros(3)
    train_step(params, opt, cams[1], imgs[1], 1, bg, "auto", 0.2, guard=guard, step=1)
    assert guard.failure() is None
    before = {k: v.detach().clone() for k, v in params.items()}
    real_loss = fit_mod.loss_fn
    monkeypatch.setattr(fit_mod, "loss_fn", lambda a, b, w: real_loss(a, b, w) * float("inf"))
    train_step(params, opt, cams[2], imgs[2], 1, bg, "auto", 0.2, guard=guard, step=2)
    monkeypatch.setattr(fit_mod, "loss_fn", real_loss)
    for k, v in params.items():
        assert torch.equal(v.detach(), before[k]), k  # skipped
    train_step(params, opt, cams[3], imgs[3], 1, bg, "auto", 0.2, guard=guard, step=3)
    assert not torch.equal(params["means"].detach(), before["means"])  # later steps go on
    assert guard.failure() == (2, "loss is inf")  # the first bad step is remembered
    with pytest.raises(FitDivergedError, match="iteration 2: loss is inf"):
        guard.check()


def test_render_passes_only_the_active_sh_bands(scene):
    from anigs.render import rasterize
    from anigs.static.fit import render_params, to_params

    gt, cams, _ = scene
    g = gt.with_sh_degree(3)
    g.sh[:, 1:] = 0.1 * torch.randn(g.sh[:, 1:].shape, generator=torch.Generator().manual_seed(0))
    params = to_params(g, torch.device("cpu"))
    cam = cams[0]
    for deg in (0, 1, 3):
        rgb, _, _ = render_params(params, cam, deg, torch.zeros(3), "auto")
        full, _, _ = rasterize(g.means, g.quats, g.scales, g.opacities, g.sh, cam.torch_viewmat(), cam.torch_K(),
                               cam.width, cam.height, sh_degree=deg, background=torch.zeros(3))
        assert torch.equal(rgb, full), deg
    rgb, _, _ = render_params(params, cam, 1, torch.zeros(3), "auto")
    rgb.sum().backward()
    assert params["sh_rest"].grad.shape == params["sh_rest"].shape
    assert torch.count_nonzero(params["sh_rest"].grad[:, 3:]) == 0 and torch.count_nonzero(params["sh_rest"].grad[:, :3])


def test_fit_reports_step_times_and_skips_statistics_after_the_last_densification(scene, monkeypatch):
    import anigs.static.fit as fit_mod

    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    seen = []
    real = fit_mod.update_state

    def spy(state, meta, w, h):
        seen.append(meta["means2d"].shape[0])
        return real(state, meta, w, h)

    monkeypatch.setattr(fit_mod, "update_state", spy)
    _, m = fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=False)
    assert len(seen) == 20  # steps 1..20: the last densification is at step 20 (stop 30, every 10)
    assert m["final_steps_from"] == 21 and m["step_ms_median_final"] > 0 and m["step_ms_median"] > 0
