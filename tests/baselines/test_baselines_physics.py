"""PhysDreamer-style physics baseline: integrator hard cases, graph, material fit, end to end."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.animate.deform import load_model
from anigs.animate.frames import render_clip
from anigs.animate.update import ViewData
from anigs.baselines import run_baseline
from anigs.baselines.base import trajectories_to_deformation
from anigs.baselines.physics import (PhysicsConfig, WindResponse, fit, fit_material, material_regions, pick_view)
from anigs.baselines.springs import ImplicitIntegrator, build_graph, simulate, stiffness_matrix
from anigs.baselines.tracks import ViewObservation, projection_jacobians
from anigs.video import save_clip
from tests._scenes import ring_cameras, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")

SCHEMES = ("midpoint", "euler")


def plant(D: int = 60, seed: int = 0):
    """Dynamic points in a column above a static ground patch: (rest [D,3], static [S,3])."""
    rng = np.random.default_rng(seed)
    X = np.c_[rng.uniform(-0.2, 0.2, D), rng.uniform(-0.2, 0.2, D), rng.uniform(0.1, 1.0, D)]
    S = np.c_[rng.uniform(-0.5, 0.5, (40, 2)), np.zeros(40)]
    return X, S


def k_norm(K, u):
    return float(np.sqrt(max((u * (K @ u)).sum(), 0.0)))


# ---- integrator hard cases ------------------------------------------------------------------
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("k, dt", [(1e12, 0.05), (1e4, 10.0), (1.0, 1e6)])
def test_stiff_springs_and_huge_steps_stay_bounded(scheme, k, dt):
    """A step force from rest: energy conservation (midpoint) or dissipation (Euler) keeps u in
    the K-ball around the static solution u_s, so |u|_K <= 2 |u_s|_K, for any stiffness and step.
    (Explicit Euler at k = 1e12, dt = 0.05 grows by ~dt sqrt(k) = 5e4 per step.)"""
    g = build_graph(*plant())
    f = np.ones((g.num_nodes, 1))
    u = simulate(g, k, 0.0, lambda t: f, dt, 50, scheme=scheme)
    K = stiffness_matrix(g, k)
    from scipy.sparse.linalg import spsolve

    us = spsolve(K.tocsc(), f[:, 0])[:, None]
    assert np.isfinite(u).all()
    assert max(k_norm(K, x) for x in u) <= 2.0 * k_norm(K, us) * (1 + 1e-6)
    if scheme == "euler" and dt >= 1e6:   # L-stable: one huge step lands on the static equilibrium
        assert np.allclose(u[1], us, rtol=1e-6, atol=0)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_very_soft_springs_bounded_by_free_motion(scheme):
    """k -> 0: each Gaussian moves at most like a free unit mass under the force, f t^2/2 (+ f t h/2 for Euler)."""
    g = build_graph(*plant())
    dt, steps = 0.05, 200
    u = simulate(g, 1e-12, 0.0, lambda t: np.ones((g.num_nodes, 1)), dt, steps, scheme=scheme)
    t = dt * np.arange(steps + 1)
    bound = t ** 2 / 2 + t * dt / 2
    assert np.all(np.abs(u[:, :, 0]) <= bound[:, None] * (1 + 1e-9) + 1e-12)
    assert np.abs(u[-1]).max() > 0.9 * t[-1] ** 2 / 2   # and it really is (almost) free


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("dt", [1e-3, 0.1, 100.0])
def test_zero_damping_energy_never_grows(scheme, dt):
    g = build_graph(*plant(seed=3))
    rng = np.random.default_rng(0)
    k = rng.uniform(1.0, 1e4, g.num_nodes)
    integ = ImplicitIntegrator(g, k, 0.0, dt, scheme)
    u, v = rng.normal(size=(g.num_nodes, 3)), rng.normal(size=(g.num_nodes, 3))
    zero = np.zeros_like(u)
    energies = [integ.energy(u, v)]
    for _ in range(100):
        u, v = integ.step(u, v, zero, zero)
        energies.append(integ.energy(u, v))
    e = np.array(energies)
    assert np.all(np.diff(e) <= 1e-9 * e[0])
    if scheme == "midpoint":   # energy-conserving without damping
        assert abs(e[-1] - e[0]) <= 1e-8 * e[0]
    else:                      # backward Euler dissipates
        assert e[-1] < e[0]


def test_single_gaussian_settles_and_unanchored_fails_clearly():
    g = build_graph(np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]))
    assert g.num_nodes == 1 and len(g.edges) == 0 and len(g.anchor_node) >= 1
    k_eff = float(stiffness_matrix(g, 4.0).toarray()[0, 0])
    for scheme in SCHEMES:
        u = simulate(g, 4.0, 2.0, lambda t: np.ones((1, 1)), 0.05, 600, scheme=scheme)
        assert u[-1, 0, 0] == pytest.approx(1.0 / k_eff, rel=1e-3)
    with pytest.raises(ValueError, match="no static Gaussian"):
        build_graph(np.array([[0.0, 0.0, 0.5]]), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="no dynamic"):
        build_graph(np.zeros((0, 3)), np.zeros((2, 3)))


def test_invalid_parameters_fail_with_clear_errors():
    g = build_graph(*plant())
    for kw, msg in (({"stiffness": -1.0}, "stiffness must be >= 0"), ({"stiffness": np.nan}, "stiffness contains NaN"),
                    ({"damping": np.inf}, "damping contains NaN or Inf"), ({"dt": 0.0}, "time step"),
                    ({"dt": float("inf")}, "time step"), ({"scheme": "rk4"}, "unknown integrator")):
        args = {"stiffness": 1.0, "damping": 0.1, "dt": 0.01, "scheme": "midpoint", **kw}
        with pytest.raises(ValueError, match=msg):
            ImplicitIntegrator(g, args["stiffness"], args["damping"], args["dt"], args["scheme"])
    with pytest.raises(FloatingPointError, match="non-finite"):
        simulate(g, 1.0, 0.1, lambda t: np.full((g.num_nodes, 1), np.inf if t > 0 else 0.0), 0.01, 3)
    with pytest.raises(ValueError, match="must be \\[D="):
        simulate(g, 1.0, 0.1, lambda t: np.zeros((3, 1)), 0.01, 3)
    for bad in ({"stiffness_bounds": [10, 1]}, {"substeps": 0}, {"integrator": "explicit"}, {"wind_freqs_hz": [-1]}):
        with pytest.raises(ValueError):
            PhysicsConfig.from_dict(bad)


def test_every_component_is_anchored_and_stiffness_is_positive_definite():
    X1, S = plant(30)
    X2 = X1 + np.array([5.0, 0.0, 0.5])          # a second plant floating far from any static point
    g = build_graph(np.r_[X1, X2], S)
    K = stiffness_matrix(g, 10.0).toarray()
    assert np.allclose(K, K.T)
    assert np.linalg.eigvalsh(K).min() > 1e-9
    assert (g.anchor_node >= 30).any() and (g.anchor_node < 30).any()


# ---- the material fit ------------------------------------------------------------------------
def synthetic_tracks(X, g, cfg, region, k_true, c_true, T, seed=0):
    """Tracks of one full-rank 'view' generated by the steady-state model with known materials."""
    wind = WindResponse(g, cfg, T)
    U = wind.steady_responses(np.asarray(k_true)[region], np.asarray(c_true)[region])
    rng = np.random.default_rng(seed)
    amp = rng.normal(size=(U.shape[2], 2))
    d3 = np.zeros((T, len(X), 3))
    d3[..., :2] = np.einsum("tdb,ba->tda", U, amp)
    J = rng.normal(size=(len(X), 2, 3)) * 50
    return ViewObservation(None, np.ones(len(X), bool), np.zeros((len(X), 2)), np.einsum("dkj,tdj->tdk", J, d3),
                           np.ones((T, len(X))), J, np.ones(len(X))), wind, U


@pytest.mark.parametrize("k_true, c_true, tol", [([20.0], [0.5], 1.05), ([20.0, 200.0], [2.0, 2.0], 1.5)])
def test_material_fit_recovers_stiffness_and_damping(k_true, c_true, tol):
    """Tracks from the model with known per-region materials (one region; two regions 10x apart):
    the fit finds them from a shared start far away (k = 100, c = 2 for every region)."""
    X, S = plant(120)
    R, T = len(k_true), 25
    cfg = PhysicsConfig(fps=12.0, regions_per_effect=R, max_evals=150, stiffness_bounds=[0.1, 1e6], grid_stiffness=25,
                        sweeps=2, scan_points=13)
    g = build_graph(X, S, cfg.k_neighbors, cfg.anchor_neighbors, cfg.anchor_radius)
    region, labels = material_regions(X, np.ones(len(X), np.int64), R)
    assert labels == [1] * R
    obs, wind, U = synthetic_tracks(X, g, cfg, region, k_true, c_true, T)
    res = fit_material(g, region, R, obs, np.arange(len(X)), cfg, T)
    print("fitted stiffness", res.stiffness, "damping", res.damping, "loss", res.loss_initial, "->", res.loss)
    assert np.all(np.abs(np.log(res.stiffness / np.asarray(k_true))) < np.log(tol))
    assert np.all(np.abs(np.log(res.damping / np.asarray(c_true))) < np.log(tol))
    assert res.loss < 0.01 < res.loss_initial
    # the implicit simulation the trajectories come from agrees with the steady state it was fitted on
    sim = wind.responses(np.asarray(k_true)[region], np.asarray(c_true)[region])
    assert np.abs(sim - U).max() < 0.03 * np.abs(U).max()


def test_physics_baseline_end_to_end(tmp_path):
    """A shrub driven by a known simulated wind, seen by four views; the baseline fits one view.
    Its motion reprojects onto that view's motion for all dynamic Gaussians (including those the
    view does not see), only the dynamic set moves, and the model file loads like ours."""
    T = 13
    G, mask = sway_scene()
    idx = torch.nonzero(mask).squeeze(1)
    X = G.means.double().numpy()[idx.numpy()]
    S = G.means.double().numpy()[~mask.numpy()]
    cfg = PhysicsConfig(fps=12.0, regions_per_effect=2, max_evals=40, grid_stiffness=9, sweeps=1, num_bases=T - 1)
    g = build_graph(X, S, cfg.k_neighbors, cfg.anchor_neighbors, cfg.anchor_radius)
    region, _ = material_regions(X, np.ones(len(X), np.int64), 2)
    U = WindResponse(g, cfg, T).responses(np.array([30.0, 300.0])[region], np.array([1.0, 3.0])[region])
    amp = np.zeros((U.shape[2], 2))
    amp[0], amp[1], amp[3] = [1.0, 0.3], [-0.5, 0.8], [0.3, 0.2]
    disp = np.zeros((T, len(X), 3))
    disp[..., :2] = np.einsum("tdb,ba->tda", U, amp)
    disp *= 0.06 / np.abs(disp).max()
    truth = torch.from_numpy(X[None] + disp)
    Gt, dt_ = trajectories_to_deformation(G, idx, truth, T - 1)
    views = [ViewData(c, render_clip(Gt, dt_, c, T)) for c in ring_cameras(4, 96, 72)]

    res = fit(G, mask, views, cfg)
    view = views[[v.camera.name for v in views].index(res.info["fit_view"])]
    J = projection_jacobians(X, view.camera)
    p_true = np.einsum("dkj,tdj->tdk", J, disp)
    p_fit = np.einsum("dkj,tdj->tdk", J, (res.trajectories - res.trajectories[:1]).numpy())
    err = np.sqrt(((p_fit - p_true) ** 2).sum(-1).mean() / (p_true ** 2).sum(-1).mean())
    print(f"physics: fit view {res.info['fit_view']}, reprojected relative RMSE {err:.3f}, info {res.info}")
    assert err < 0.5
    assert res.info["relative_residual"] < 0.5
    for t in (0, 6, T - 1):
        gt_ = res.deformation(res.canonical, t)
        assert torch.equal(gt_.means[~mask], G.means[~mask])

    # the CLI-level entry point: model.pt from paths, fit on a named view
    ply = tmp_path / "canonical.ply"
    G.save_ply(ply)
    np.save(tmp_path / "dynamic.npy", mask.numpy())
    targets = []
    for v in views:
        targets.append(tmp_path / f"{v.camera.name}.npz")
        save_clip(targets[-1], v.clip.numpy(), {"camera": v.camera.to_dict()})
    out = tmp_path / "model.pt"
    r2 = run_baseline("physics", ply, tmp_path / "dynamic.npy", targets, out,
                      {**cfg.to_dict(), "fit_view": "v1", "max_evals": 0, "grid_stiffness": 1, "sweeps": 0})
    canon, d, payload = load_model(out, ply)
    assert payload["extra"]["info"]["fit_view"] == "v1" and r2.info["evaluations"] == 1
    assert render_clip(canon, d, views[1].camera, T).shape == views[1].clip.shape


def test_only_the_scene_effects_are_simulated_and_view_choice():
    G, mask = sway_scene(n_dyn=60, grid=7)
    labels = torch.zeros(G.num, dtype=torch.long)
    dyn = torch.nonzero(mask).squeeze(1)
    labels[dyn[:30]], labels[dyn[30:]] = 2, 5      # two effect labels; 0 = static
    cams = ring_cameras(2, 64, 48)
    clip = render_clip(G, None, cams[0], 5)
    views = [ViewData(cams[0], clip), ViewData(cams[1], render_clip(G, None, cams[1], 5))]
    res = fit(G, labels, views, {"regions_per_effect": 2, "max_evals": 0, "grid_stiffness": 1, "sweeps": 0, "fps": 12.0})
    assert sorted(set(res.info["region_labels"])) == [2, 5]
    assert res.deformation.num_dynamic == 60
    # a still target clip: the fitted wind is (numerically) zero, nothing moves
    assert res.info["displacement_max"] < 1e-6
    none = fit(G, torch.zeros(G.num, dtype=torch.long), views)
    assert none.info["skipped"] == "empty dynamic set" and none.deformation.num_dynamic == 0
    cfg = PhysicsConfig(fit_view="nope")
    with pytest.raises(ValueError, match="not one of the views"):
        pick_view(G, dyn, views, cfg)
    with pytest.raises(ValueError, match="out of range"):
        pick_view(G, dyn, views, PhysicsConfig(fit_view=7))
    assert pick_view(G, dyn, views, PhysicsConfig(fit_view=1)) == 1
