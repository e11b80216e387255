"""Needle and unresolved-Gaussian control of the static fit (anigs.static.regularize)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.static.fit import StaticConfig, to_params, fit_static, make_optimizer
from anigs.static.regularize import (NeedleRegularizer, RegularizeConfig, last_densify_step, limit_needles,
                                     prune_rows)
from anigs.gaussians import Gaussians

pytestmark = pytest.mark.usefixtures("one_thread")


def _ring(n: int = 8, width: int = 80, height: int = 60) -> list[Camera]:
    K = intrinsics_from_fov(60, width, height)
    return [Camera(K, look_at((4 * math.cos(2 * math.pi * i / n), 4 * math.sin(2 * math.pi * i / n), 1.0), (0, 0, 0.3)),
                   width, height, f"c{i}") for i in range(n)]


def _scene_with_needle() -> Gaussians:
    """A 5x5x3 grid of small Gaussians (ordinary: flat disks and round blobs) plus, last, one
    needle 2 units long above them and, before it, one huge blob."""
    xs = np.linspace(-0.8, 0.8, 5)
    pts = np.array([(x, y, z) for x in xs for y in xs for z in (0.0, 0.3, 0.6)])
    scales = np.full((len(pts), 3), 0.05)
    scales[::2, 2] = 0.004  # flat disks: two large axes, ratio 12.5 against the smallest, 1 against the middle
    pts = np.vstack([pts, [[0.0, 0.0, 1.2], [0.2, 0.0, 1.5]]])
    scales = np.vstack([scales, [[1.5, 1.5, 1.5], [2.0, 0.02, 0.02]]])
    return Gaussians.from_points(torch.tensor(pts).float(), torch.rand(len(pts), 3, generator=torch.Generator().manual_seed(0)),
                                 torch.tensor(scales).float(), opacity=0.8)


def test_needle_limit_shrinks_needles_and_leaves_disks_and_blobs():
    g = _scene_with_needle()
    ls = g.log_scales.clone()
    before = ls.clone()
    limit_needles(ls, 10.0)
    s = ls.exp()
    assert s[-1].max() == pytest.approx(0.2, rel=1e-4)  # 10 x its middle scale 0.02
    assert torch.equal(ls[:-1], before[:-1])            # disks (ratio 1 to the middle axis) and blobs untouched
    limit_needles(ls, 0.0)                               # 0: off
    assert s[-1].max() == pytest.approx(0.2, rel=1e-4)


def test_unresolved_flags_the_needle_and_the_huge_blob_only():
    g = _scene_with_needle()
    cams = _ring()
    params = to_params(g, torch.device("cpu"))
    reg = NeedleRegularizer(RegularizeConfig(max_world_fraction=0.1, max_share=1.0), extent=4.4, cameras=cams,
                            mats=[(c.torch_viewmat(), c.torch_K()) for c in cams])
    bad = reg.unresolved(params)
    assert bad[-2:].all() and not bad[:-2].any()
    op_before = params["opacity_logits"].detach().clone()
    assert reg.decay(params, 300) == 2
    op = torch.sigmoid(params["opacity_logits"].detach())
    assert op[-2:] == pytest.approx([0.4, 0.4], abs=1e-4)
    assert torch.equal(params["opacity_logits"].detach()[:-2], op_before[:-2])
    opt = make_optimizer(params, {k: 1e-3 for k in params})
    keep = reg.final_keep(params)
    pruned = prune_rows(params, opt, keep)
    assert pruned["means"].shape[0] == g.num - 2
    assert torch.equal(pruned["means"].detach(), g.means[:-2])


def test_the_last_densification_step_prunes_what_is_unresolved():
    g = _scene_with_needle()
    cams = _ring()
    params = to_params(g, torch.device("cpu"))
    reg = NeedleRegularizer(RegularizeConfig(max_share=1.0), extent=4.4, cameras=cams,
                            mats=[(c.torch_viewmat(), c.torch_K()) for c in cams])
    assert reg.decay(params, 700, last=True) == 2
    op = torch.sigmoid(params["opacity_logits"].detach())
    assert (op[-2:] < 1e-6).all() and (op[:-2] == pytest.approx(0.8, abs=1e-5))  # below any prune opacity
    # nothing unresolved is left for the end; the two zeroed ones are also unseen (densification's opacity
    # prune removes them in a fit; here they are still there), everything else is seen
    keep = reg.final_keep(params)
    assert keep is not None and keep[:-2].all() and not keep[-2:].any()
    assert reg.report(params)["final_pruned"] == 2
    off = NeedleRegularizer(RegularizeConfig(max_share=1.0, min_seen_weight=0.0), extent=4.4, cameras=cams,
                            mats=[(c.torch_viewmat(), c.torch_K()) for c in cams])
    off.decay(params, 700, last=True)
    assert off.final_keep(params) is None
    assert last_densify_step(300, 800, 100, 1000) == 700
    assert last_densify_step(300, 1200, 100, 1000) == 1000
    assert last_densify_step(300, 800, 100, 250) is None


def test_a_coarse_model_loses_at_most_max_share_its_least_resolved_first():
    g = _scene_with_needle()
    g.log_scales[:] = math.log(0.6)          # every splat large: unresolved in every photo
    g.log_scales[7] = math.log(2.0)          # the two worst
    g.log_scales[9] = math.log(1.5)
    cams = _ring()
    params = to_params(g, torch.device("cpu"))
    mats = [(c.torch_viewmat(), c.torch_K()) for c in cams]
    cap = NeedleRegularizer(RegularizeConfig(max_share=2 / g.num), 4.4, cams, mats).unresolved(params)
    assert cap.sum() == 2 and cap[7] and cap[9]
    assert NeedleRegularizer(RegularizeConfig(max_share=1.0), 4.4, cams, mats).unresolved(params).all()


def test_config_validation():
    with pytest.raises(ValueError, match="max_needle_ratio"):
        RegularizeConfig.from_dict({"max_needle_ratio": 0.5})
    with pytest.raises(ValueError, match="decay"):
        RegularizeConfig.from_dict({"decay": 0.0})
    with pytest.raises(ValueError):
        StaticConfig.from_dict({"regularize": {"no_such_key": 1}})
    assert StaticConfig.from_dict({"regularize": {"enabled": False}}).regularize.enabled is False


def test_fit_keeps_every_gaussian_within_the_needle_limit():
    """A fit with the regulariser ends with no Gaussian longer than 10x its middle axis; the
    switch turns it off (recorded in the metrics)."""
    from tests.static.test_fit import FAST, make_scene, sfm_points

    gt, cams, imgs = make_scene()
    pts, cols = sfm_points(gt)
    cfg = StaticConfig.from_dict({**FAST, "iterations": 60, "densify": {"start": 20, "stop": 50, "every": 10}})
    g, m = fit_static(imgs, cams, pts, cols, cfg, progress=False)
    s = g.scales.sort(1).values
    assert float((s[:, 2] / s[:, 1]).max()) <= 10.0 + 1e-3
    assert m["regularize"]["max_needle_ratio_after"] <= 10.0 + 1e-3
    off = StaticConfig.from_dict({**FAST, "iterations": 60, "densify": {"start": 20, "stop": 50, "every": 10},
                               "regularize": {"enabled": False}})
    g0, m0 = fit_static(imgs, cams, pts, cols, off, progress=False)
    assert m0["regularize"]["enabled"] is False


def test_unseen_gaussians_are_the_hidden_and_the_outside():
    from anigs.static.regularize import unseen

    g = _scene_with_needle()
    cams = _ring()
    means = torch.cat([g.means, torch.tensor([[0.0, 0.0, 50.0], [0.0, 0.0, 0.0]])])  # far above every camera; the centre
    g2 = type(g)(means, torch.cat([g.quats, g.quats[:2]]), torch.cat([g.log_scales, g.log_scales[:2]]),
                 torch.cat([g.opacity_logits, g.opacity_logits[:2]]), torch.cat([g.sh, g.sh[:2]]))
    hidden = unseen(to_params(g2, torch.device("cpu")), cams, 0.01)
    assert hidden[-2] and not hidden[:-2].any()
