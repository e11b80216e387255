"""Densification strategy: state accumulation, clone/split/prune, budget, opacity reset, Adam moments."""
from __future__ import annotations

import math

import pytest
import torch

from anigs.static.densify import (AllPrunedError, DensifyConfig, DensifyState, refine, refine_due, reset_opacity,
                                  stats_needed, update_state)

pytestmark = pytest.mark.usefixtures("one_thread")


def make_params(n: int, scale: float = 0.01, opacity: float = 0.5, seed: int = 0, fused: bool = False):
    g = torch.Generator().manual_seed(seed)
    P = torch.nn.Parameter
    params = {
        "means": P(torch.randn(n, 3, generator=g)),
        "quats": P(torch.nn.functional.normalize(torch.randn(n, 4, generator=g), dim=1)),
        "log_scales": P(torch.full((n, 3), math.log(scale))),
        "opacity_logits": P(torch.full((n,), math.log(opacity / (1 - opacity)))),
        "sh_dc": P(torch.randn(n, 1, 3, generator=g)),
        "sh_rest": P(torch.zeros(n, 3, 3)),
    }
    opt = torch.optim.Adam([{"params": [v], "lr": 1e-3, "name": k} for k, v in params.items()], eps=1e-15,
                           fused=fused or None)
    return params, opt


def take_adam_step(params, opt):
    loss = sum((v.float() ** 2).sum() for v in params.values())
    loss.backward()
    opt.step()
    opt.zero_grad()


def state_with_grads(n: int, grads: list[float], radii: list[float] | None = None) -> DensifyState:
    st = DensifyState.empty(n)
    st.grad_sum = torch.tensor(grads, dtype=torch.float32)
    st.count = torch.ones(n)
    if radii is not None:
        st.max_radii = torch.tensor(radii, dtype=torch.float32)
    return st


CFG = DensifyConfig(growth="threshold", start=1, stop=1000, every=1, grad_threshold=0.001, dense_percent=0.05,
                    reset_every=0, max_gaussians=100)


def test_config_rejects_unknown_keys():
    with pytest.raises(ValueError, match="grad_treshold"):
        DensifyConfig.from_dict({"grad_treshold": 1.0})
    assert DensifyConfig.from_dict({"every": 50}).every == 50
    with pytest.raises(ValueError, match="every"):
        DensifyConfig.from_dict({"every": 0})


def test_update_state_needs_retained_grad():
    means2d = torch.zeros(3, 2, requires_grad=True) * 1.0  # non-leaf, grad not retained
    (means2d.sum()).backward()
    with pytest.raises(RuntimeError, match="retain_grad"):
        update_state(DensifyState.empty(3), {"means2d": means2d, "radii": torch.ones(3, dtype=torch.int32)}, 10, 10)


def test_update_state_accumulates_visible_in_ndc_units():
    base = torch.zeros(3, 2, requires_grad=True)
    means2d = base * 1.0
    means2d.retain_grad()
    w = torch.tensor([[1.0, 0.0], [0.0, 2.0], [5.0, 5.0]])
    (means2d * w).sum().backward()
    st = DensifyState.empty(3)
    radii = torch.tensor([4, 2, 0], dtype=torch.int32)
    update_state(st, {"means2d": means2d, "radii": radii}, width=100, height=50)
    update_state(st, {"means2d": means2d, "radii": radii}, width=100, height=50)
    # x gradient scaled by W/2 = 50, y by H/2 = 25; the culled third Gaussian is not counted
    assert torch.allclose(st.grad_sum, torch.tensor([100.0, 100.0, 0.0]))
    assert torch.equal(st.count, torch.tensor([2.0, 2.0, 0.0]))
    assert torch.allclose(st.max_radii, torch.tensor([0.04, 0.02, 0.0]))


def test_update_state_rejects_size_mismatch():
    m = torch.zeros(2, 2, requires_grad=True)
    m.sum().backward()
    with pytest.raises(ValueError, match="3 rows"):
        update_state(DensifyState.empty(3), {"means2d": m, "radii": torch.ones(2)}, 10, 10)


@pytest.mark.parametrize("fused", [False, True])
def test_clone_small_and_split_large_keep_adam_moments_consistent(fused):
    params, opt = make_params(4, scale=0.01, fused=fused)
    with torch.no_grad():
        params["log_scales"][1] = math.log(0.5)  # large: will be split (extent 1, dense_percent 0.05)
    take_adam_step(params, opt)
    old_means = params["means"].detach().clone()
    parent_scale = params["log_scales"][1].detach().exp()
    old_m = {k: opt.state[v]["exp_avg"].clone() for k, v in params.items()}
    old_v = {k: opt.state[v]["exp_avg_sq"].clone() for k, v in params.items()}
    st = state_with_grads(4, [0.01, 0.01, 0.0, 0.0])  # 0 -> clone, 1 -> split, 2 and 3 untouched
    new = refine(params, opt, st, step=5, cfg=CFG, scene_extent=1.0, generator=torch.Generator().manual_seed(0))
    assert new["means"].shape[0] == 4 + 1 + 1  # one clone, one split (2 children replace 1)
    assert st.last["cloned"] == 1 and st.last["split"] == 1
    # kept rows first (0, 2, 3), then the clone of 0, then the two children of 1
    assert torch.equal(new["means"][:3].detach(), old_means[[0, 2, 3]])
    assert torch.equal(new["means"][3].detach(), old_means[0])
    children = new["log_scales"][4:].detach().exp()
    assert torch.allclose(children, (parent_scale / CFG.split_factor).expand(2, 3))
    assert not torch.equal(new["means"][4], new["means"][5])
    # optimizer now holds the new tensors; moments: kept rows carried, new rows zero
    for k, v in new.items():
        group = next(g for g in opt.param_groups if g["name"] == k)
        assert group["params"][0] is v
        m, v2 = opt.state[v]["exp_avg"], opt.state[v]["exp_avg_sq"]
        assert m.shape == v.shape and v2.shape == v.shape
        assert torch.equal(m[:3], old_m[k][[0, 2, 3]]) and torch.equal(v2[:3], old_v[k][[0, 2, 3]])
        assert torch.count_nonzero(m[3:]) == 0 and torch.count_nonzero(v2[3:]) == 0
        assert float(opt.state[v]["step"]) == 1  # the step count moves with the moments
    assert len(opt.state) == len(new)  # no state left on the replaced tensors
    assert st.num == 6 and float(st.grad_sum.sum()) == 0
    take_adam_step(new, opt)  # the optimizer still works with the new shapes
    assert all(float(opt.state[v]["step"]) == 2 for v in new.values())


def test_prune_low_opacity_and_too_large_after_reset():
    params, opt = make_params(5)
    with torch.no_grad():
        params["opacity_logits"][0] = math.log(0.001 / 0.999)
        params["log_scales"][3] = math.log(0.3)  # > 0.1 * extent in the world
    take_adam_step(params, opt)
    cfg = DensifyConfig(growth="threshold", start=1, stop=1000, every=1, grad_threshold=1.0, reset_every=0, prune_size_from=100,
                        max_gaussians=100)
    st = state_with_grads(5, [0.0] * 5, radii=[0.0, 0.0, 0.5, 0.0, 0.0])  # 2 too large on screen
    means = params["means"].detach().clone()
    new = refine(params, opt, st, step=50, cfg=cfg, scene_extent=1.0)  # before prune_size_from: only opacity
    assert new["means"].shape[0] == 4
    assert torch.equal(new["means"].detach(), means[1:])
    st = state_with_grads(4, [0.0] * 4, radii=[0.0, 0.5, 0.0, 0.0])
    new2 = refine(new, opt, st, step=101, cfg=cfg, scene_extent=1.0)
    assert torch.equal(new2["means"].detach(), means[[1, 4]])
    assert opt.state[new2["means"]]["exp_avg"].shape == (2, 3)


def test_budget_keeps_highest_gradients():
    params, opt = make_params(6)
    cfg = DensifyConfig(growth="threshold", start=1, stop=1000, every=1, grad_threshold=0.001, reset_every=0, max_gaussians=8)
    st = state_with_grads(6, [0.002, 0.009, 0.003, 0.008, 0.004, 0.0])
    means = params["means"].detach().clone()
    new = refine(params, opt, st, step=3, cfg=cfg, scene_extent=100.0)
    assert new["means"].shape[0] == 8
    assert torch.equal(new["means"][6:].detach(), means[[1, 3]])  # the two largest gradients were cloned


def test_all_pruned_raises_clear_error():
    params, opt = make_params(3, opacity=0.001)
    with pytest.raises(AllPrunedError, match="all 3 Gaussians"):
        refine(params, opt, state_with_grads(3, [0.0] * 3), step=10, cfg=CFG, scene_extent=1.0)


def test_schedule_outside_window_is_a_no_op():
    params, opt = make_params(3, opacity=0.001)
    cfg = DensifyConfig(growth="threshold", start=100, stop=200, every=10, reset_every=0)
    st = state_with_grads(3, [1.0] * 3)
    for step in (5, 105, 200, 300):  # before start, off-interval, at stop, after stop
        assert refine(params, opt, st, step, cfg, 1.0) is params


def test_opacity_reset_clamps_and_zeros_moments():
    params, opt = make_params(3, opacity=0.9)
    with torch.no_grad():
        params["opacity_logits"][2] = math.log(0.001 / 0.999)
    take_adam_step(params, opt)
    reset_opacity(params, opt, 0.01)
    op = torch.sigmoid(params["opacity_logits"].detach())
    assert torch.allclose(op[:2], torch.full((2,), 0.01), atol=1e-6)
    assert op[2] < 0.002  # lower opacities are not raised
    assert torch.count_nonzero(opt.state[params["opacity_logits"]]["exp_avg"]) == 0


def test_split_is_deterministic_for_a_seed():
    outs = []
    for _ in range(2):
        params, opt = make_params(4, scale=0.5)
        st = state_with_grads(4, [0.01] * 4)
        new = refine(params, opt, st, 1, CFG, 1.0, torch.Generator().manual_seed(7))
        outs.append(new["means"].detach())
    assert torch.equal(outs[0], outs[1])


def test_with_rasterizer_meta():
    from anigs.cameras import intrinsics_from_fov, look_at
    from anigs.render import rasterize

    params, opt = make_params(50, scale=0.05, seed=1)
    K = torch.tensor(intrinsics_from_fov(60, 64, 48), dtype=torch.float32)
    V = torch.tensor(look_at((0, -5, 0), (0, 0, 0)), dtype=torch.float32)
    rgb, _, meta = rasterize(params["means"], params["quats"], params["log_scales"].exp(),
                             torch.sigmoid(params["opacity_logits"]), params["sh_dc"][:, 0], V, K, 64, 48)
    meta["means2d"].retain_grad()
    (rgb - 0.3).abs().mean().backward()
    st = DensifyState.empty(50)
    update_state(st, meta, 64, 48)
    vis = meta["radii"] > 0
    assert vis.any()
    assert torch.all(st.count[vis] == 1) and torch.all(st.count[~vis] == 0)
    assert float(st.grad_sum[vis].sum()) > 0


def test_refine_resets_opacity_on_schedule():
    params, opt = make_params(3, opacity=0.9)
    cfg = DensifyConfig(growth="threshold", start=1000, stop=2000, every=100, reset_every=50)
    st = state_with_grads(3, [0.0] * 3)
    refine(params, opt, st, 49, cfg, 1.0)
    assert torch.sigmoid(params["opacity_logits"].detach()).min() > 0.8
    refine(params, opt, st, 50, cfg, 1.0)
    assert torch.sigmoid(params["opacity_logits"].detach()).max() <= 0.01 + 1e-6
    assert st.last.get("opacity_reset") == 1


def test_schedule_ends_densification_before_the_fit_ends():
    """A fit shorter than densify.stop still ends with steps free of densification."""
    from anigs.static.densify import DensifyConfig, schedule_for

    cfg = DensifyConfig(growth="threshold", start=300, stop=1200, every=100)
    assert schedule_for(cfg, 500).stop == 400 and schedule_for(cfg, 1000).stop == 800
    assert schedule_for(cfg, 3000).stop == 1200  # a long fit keeps the configured stop
    assert schedule_for(DensifyConfig(growth="threshold", stop_fraction=1.0), 1000).stop == 1000
    with pytest.raises(ValueError, match="stop_fraction"):
        DensifyConfig.from_dict({"stop_fraction": 0})


def test_statistics_are_needed_until_the_last_scheduled_densification():
    cfg = DensifyConfig(growth="threshold", start=300, stop=800, every=100)
    assert [s for s in (1, 299, 700, 701, 800, 1000) if stats_needed(cfg, s)] == [1, 299, 700]
    assert not stats_needed(DensifyConfig(growth="threshold", start=300, stop=250, every=100), 1)  # nothing scheduled
    assert stats_needed(DensifyConfig(growth="threshold", start=10, stop=31, every=10), 30)
    assert not stats_needed(DensifyConfig(growth="threshold", start=10, stop=30, every=10), 21)  # 30 is not < stop


def test_refine_due_matches_what_refine_does():
    cfg = DensifyConfig(growth="threshold", start=5, stop=20, every=5, reset_every=8)
    params, opt = make_params(6, scale=0.01)
    for step in range(1, 25):
        st = state_with_grads(params["means"].shape[0], [0.0] * params["means"].shape[0])
        before = params["opacity_logits"].detach().clone()
        params = refine(params, opt, st, step, cfg, scene_extent=1.0)
        changed = bool(st.last) or not torch.equal(before, params["opacity_logits"].detach())
        assert changed == refine_due(cfg, step), step


def test_budget_growth_follows_its_line_by_rank_not_by_threshold():
    from anigs.static.densify import growth_target

    cfg = DensifyConfig(start=300, stop=1000, every=100, grad_threshold=0.01, max_gaussians=100, reset_every=0)
    # densifications at 300..900: seven steps from the first size to the budget
    assert [growth_target(cfg, s, 30) for s in range(300, 1000, 100)] == [40, 50, 60, 70, 80, 90, 100]
    params, opt = make_params(30)
    grads = [0.1 * (i + 1) / 30 for i in range(30)]  # all far above the threshold
    st = state_with_grads(30, grads)
    new = refine(params, opt, st, step=300, cfg=cfg, scene_extent=100.0)
    assert new["means"].shape[0] == 40  # the line, not every candidate
    assert st.first_count == 30
    # scaled gradients (another image size) pick the same Gaussians: a rank, not a threshold
    p2, o2 = make_params(30)
    new2 = refine(p2, o2, state_with_grads(30, [g * 0.3 for g in grads]), step=300, cfg=cfg, scene_extent=100.0)
    assert torch.equal(new["means"].detach(), new2["means"].detach())
    # below a quarter of the threshold nothing grows
    p3, o3 = make_params(30)
    assert refine(p3, o3, state_with_grads(30, [0.002] * 30), step=300, cfg=cfg, scene_extent=100.0)["means"].shape[0] == 30
    with pytest.raises(ValueError, match="densify.growth"):
        DensifyConfig.from_dict({"growth": "fast"})
