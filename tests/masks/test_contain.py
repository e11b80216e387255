"""Containment of the dynamic set (anigs.masks.contain): a halo that spills out of the masks stays
still, a compact Gaussian inside them keeps moving, and then nothing outside the masks changes."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.cameras import Camera, intrinsics_from_fov
from anigs.gaussians import Gaussians
from anigs.masks.contain import contain_dynamic, outside_weights
from anigs.render.labels import dynamic_masks
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.synth.scene import SKY

W, H = 64, 48
BG = SKY


def _scene():
    """Camera at the origin looking down +z; a textured static wall at z = 8 filling the view, a
    compact cluster of small Gaussians at z = 5 (what moves), one large translucent halo centred on
    the cluster whose footprint covers much of the wall, and a small Gaussian hidden behind the wall.
    Returns (Gaussians, index dict, camera)."""
    rng = np.random.default_rng(0)
    ys, xs = np.meshgrid(np.linspace(-7, 7, 57), np.linspace(-9, 9, 73))
    wall = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, 8.0)], 1)
    cluster = np.array([0.0, 0.0, 5.0]) + rng.uniform(-0.5, 0.5, (60, 3)) * [1, 1, 0.2]
    halo = np.array([[0.0, 0.0, 4.9]])
    hidden = np.array([[4.0, 0.0, 9.0]])  # behind the opaque wall
    pts = np.concatenate([wall, cluster, halo, hidden])
    cols = np.concatenate([rng.uniform(0.2, 0.8, (len(wall), 3)), np.tile([0.1, 0.6, 0.1], (len(cluster), 1)),
                           [[0.2, 0.5, 0.2]], [[0.9, 0.1, 0.1]]])
    g = Gaussians.from_points(torch.tensor(pts, dtype=torch.float32), torch.tensor(cols, dtype=torch.float32),
                              0.05, opacity=0.99)
    scales = np.concatenate([np.full((len(wall), 3), 0.3), np.full((len(cluster), 3), 0.06),
                             [[1.5, 1.0, 0.3]], [[0.5, 0.5, 0.3]]])
    g.log_scales = torch.tensor(scales, dtype=torch.float32).log()
    op = np.concatenate([np.full(len(wall) + len(cluster), 0.99), [0.25], [0.99]])
    g.opacity_logits = torch.logit(torch.tensor(op, dtype=torch.float32))
    n0 = len(wall)
    index = {"cluster": np.arange(n0, n0 + len(cluster)), "halo": n0 + len(cluster), "hidden": n0 + len(cluster) + 1}
    cam = Camera(intrinsics_from_fov(60, W, H), np.eye(4), W, H, "v00")
    return g, index, cam


def _flags(n, *rows):
    f = np.zeros(n, bool)
    for r in rows:
        f[r] = True
    return f


@pytest.fixture(scope="module")
def scene():
    g, index, cam = _scene()
    truth = _flags(g.num, index["cluster"])  # what should move
    mask = dynamic_masks(g, truth, [cam])[0]  # the honest mask: the render of the cluster
    assert 0.02 < mask.mean() < 0.4
    return g, index, cam, truth, mask


def test_halo_is_frozen_compact_gaussians_keep_moving(scene):
    g, index, cam, _, mask = scene
    lifted = _flags(g.num, index["cluster"], index["halo"], index["hidden"])
    res = contain_dynamic(g, lifted, [cam], [mask], margin_px=3, max_outside_px=0.05)
    assert not res.dynamic[index["halo"]]
    assert res.dynamic[index["cluster"]].all()
    assert res.dynamic[index["hidden"]]  # no weight anywhere in this view: nothing to judge it by
    assert res.outside[index["halo"]] > 10 and res.worst_view[index["halo"]] == 0
    assert (res.outside[~lifted] == 0).all() and (res.worst_view[~lifted] == -1).all()
    assert not (res.dynamic & ~lifted).any()  # containment only ever removes
    info = res.info(lifted, ["v00"], 3, 0.05)
    assert info["frozen"] == 1 and info["frozen_by_view"] == {"v00": 1}
    assert info["dynamic_before"] - info["dynamic_after"] == 1
    # deterministic
    again = contain_dynamic(g, lifted, [cam], [mask], margin_px=3, max_outside_px=0.05)
    np.testing.assert_array_equal(again.outside, res.outside)


def test_contained_motion_leaves_the_outside_still(scene):
    """With the halo moving, pixels far outside the mask change; with the contained set, none
    outside the 5 px band does, while the cluster still moves inside the mask."""
    from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask
    from anigs.animate.frames import render_clip
    from anigs.metrics.motion import clip_motion_metrics, outside_mask_still

    g, index, cam, _, mask = scene
    lifted = _flags(g.num, index["cluster"], index["halo"])
    contained = contain_dynamic(g, lifted, [cam], [mask]).dynamic

    def clip(flags):
        d = DCTDeformation(dynamic_index_from_mask(torch.from_numpy(flags)), 9, 4, rotation=False,
                           num_gaussians=g.num)
        with torch.no_grad():
            d.pos_coeffs.copy_(torch.randn(d.pos_coeffs.shape, generator=torch.Generator().manual_seed(1)) * 0.1)
        return render_clip(g, d, cam, 9, BG).numpy()

    spill, kept = clip(lifted), clip(contained)
    assert outside_mask_still(spill, mask) < 0.9
    assert outside_mask_still(kept, mask) == 1.0
    assert clip_motion_metrics(kept, mask, with_flow=False).dynamic_abs_diff > 1e-3  # the cluster moves


def test_outside_weights_margin_and_errors(scene):
    g, index, cam, truth, mask = scene
    w0 = outside_weights(g, [cam], [mask], margin_px=0)
    w5 = outside_weights(g, [cam], [mask], margin_px=5)
    assert w0.shape == (1, g.num) and (w5 <= w0 + 1e-9).all()  # a wider band forgives more
    assert w0[0, index["halo"]] > w5[0, index["halo"]] > 0
    from anigs.masks.contain import _outside_region, _reaching
    from anigs.render.visibility import blend_weights

    out, dist = _outside_region(mask, cam, 5)
    assert len(_reaching(g, cam, dist)) < g.num  # the cull leaves out what cannot reach those pixels...
    np.testing.assert_allclose(w5[0], blend_weights(g, cam, out)[1], atol=1e-6)  # ...and changes no weight
    with pytest.raises(ValueError, match="margin_px"):
        outside_weights(g, [cam], [mask], margin_px=-1)
    with pytest.raises(ValueError, match="masks"):
        outside_weights(g, [cam], [], margin_px=1)
    with pytest.raises(ValueError, match="max_outside_px"):
        contain_dynamic(g, truth, [cam], [mask], max_outside_px=-1.0)
    with pytest.raises(ValueError, match="shape"):
        contain_dynamic(g, truth[:-1], [cam], [mask])
    empty = contain_dynamic(g, np.zeros(g.num, bool), [cam], [mask])
    assert not empty.dynamic.any()


def test_masks_stage_contains_the_effects_set(tmp_path):
    """`anigs masks`: the halo of the effects stage's set is left out of the dynamic set (and reported
    in the masks report); the masks stay the render of the effects set; ``contain: false`` keeps the halo."""
    import json

    from anigs.cli import main
    from anigs.effects.config import REGIONS
    from anigs.images import read_mask_png

    g, index, cam = _scene()
    g.save_ply(tmp_path / "canonical.ply")
    (tmp_path / "views.json").write_text(json.dumps({"views": [{"id": "v00", "camera": cam.to_dict()}],
                                                     "up": [0, -1, 0]}))
    eff = tmp_path / "effects"
    eff.mkdir()
    regions = np.full(g.num, -1, np.int8)
    regions[index["cluster"]] = regions[index["halo"]] = REGIONS.index("foliage")
    np.save(EffectsOutputs(eff).path("regions"), regions)
    np.save(EffectsOutputs(eff).path("dynamic"), regions >= 0)
    EffectsOutputs(eff).path("effects").write_text(json.dumps({"chosen": ["foliage_sway"]}))
    args = ["masks", "--canonical", str(tmp_path / "canonical.ply"), "--views", str(tmp_path),
            "--effects", str(eff)]
    assert main(args + ["--out", str(tmp_path / "on"), "--params", "{}"]) == 0
    assert main(args + ["--out", str(tmp_path / "off"), "--params", json.dumps({"contain": False})]) == 0
    on, off = MasksOutputs(tmp_path / "on").dynamic(), MasksOutputs(tmp_path / "off").dynamic()
    np.testing.assert_array_equal(off, regions >= 0)
    assert not on[index["halo"]] and on[index["cluster"]].all() and on.sum() == off.sum() - 1
    info = MasksOutputs(tmp_path / "on").report()
    assert info["containment"]["frozen"] == 1 and info["containment"]["margin_px"] == 3
    assert "containment" not in MasksOutputs(tmp_path / "off").report()
    np.testing.assert_array_equal(read_mask_png(MasksOutputs(tmp_path / "on").path("mask", view="v00")), read_mask_png(MasksOutputs(tmp_path / "off").path("mask", view="v00")))
    assert main(args + ["--out", str(tmp_path / "x"), "--params", json.dumps({"contain_margin_px": -1})]) == 1


def _deformation(g, flags, scale=0.05, sway=None, T=9):
    """DCT motion of the flagged Gaussians; ``sway`` {row of g: metres}: those sway along x at the first basis."""
    from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask

    d = DCTDeformation(dynamic_index_from_mask(torch.from_numpy(flags)), T, 4, rotation=False, num_gaussians=g.num)
    with torch.no_grad():
        d.pos_coeffs.copy_(torch.randn(d.pos_coeffs.shape, generator=torch.Generator().manual_seed(2)) * scale)
        for i, metres in (sway or {}).items():
            row = int((d.dynamic_index == i).nonzero())
            d.pos_coeffs[row] = 0.0
            d.pos_coeffs[row, 0, 0] = metres
    return d


def test_motion_that_leaves_the_mask_moves_less_or_stops(scene):
    """Compact Gaussians inside the mask whose motion carries them out of it are caught by the
    containment of the motion (the footprint test at rest cannot see them): a moderate sway is
    scaled down until it stays inside, a wild one stops; small motions are untouched."""
    from anigs.animate.frames import render_clip
    from anigs.masks.contain import contain_motion, scaled_motion
    from anigs.metrics.motion import outside_mask_still

    g, index, cam, truth, mask = scene
    edge = index["cluster"][np.argsort(g.means[index["cluster"], 0].numpy())]
    mid, wild = int(edge[-1]), int(edge[-2])  # the two right-most Gaussians of the cluster
    d = _deformation(g, truth, sway={mid: 0.6, wild: 8.0})  # up to ~4 px and ~55 px sideways at z = 5
    assert contain_dynamic(g, truth, [cam], [mask]).dynamic[[mid, wild]].all()  # both sit inside at rest
    factor, outside, worst = contain_motion(g, d, [cam], [mask], margin_px=3, max_outside_px=0.05)
    rows = d.dynamic_index.numpy()
    assert 0 < factor[rows == mid][0] < 1 and factor[rows == wild][0] == 0
    assert (factor[(rows != mid) & (rows != wild)] == 1).all()
    assert outside[rows == wild][0] > 0.05 and worst[rows == wild][0] == 0
    contained = scaled_motion(d, factor)
    contained = contained.remapped(contained.dynamic_index[torch.from_numpy(factor > 0)])
    with torch.no_grad():
        before = render_clip(g, d, cam, 9, BG).numpy()
        after = render_clip(g, contained, cam, 9, BG).numpy()
    assert outside_mask_still(before, mask) < 0.999  # the two sweep over the wall
    assert outside_mask_still(after, mask) == 1.0
    assert np.abs(after - after[:1]).max() > 0.05  # the rest still moves
    # a second view that sees nothing outside its mask changes nothing; the leaks are found in view 0
    full = np.ones_like(mask)
    f2, _, w2 = contain_motion(g, d, [cam, cam], [full, mask], margin_px=3, max_outside_px=0.05)
    np.testing.assert_array_equal(f2, factor)
    assert w2[rows == wild][0] == 1
    # scaled_motion scales every coefficient; a fixed set of frames; the empty set; bad steps
    half = scaled_motion(d, np.full(d.num_dynamic, 0.5))
    assert torch.allclose(half.pos_coeffs, d.pos_coeffs * 0.5)
    f0, _, _ = contain_motion(g, d, [cam], [mask], times=[0.0], steps=())
    assert set(np.unique(f0).tolist()) <= {0.0, 1.0} and (f0 >= (factor == 1)).all()
    empty = _deformation(g, np.zeros(g.num, bool))
    assert contain_motion(g, empty, [cam], [mask])[0].shape == (0,)
    with pytest.raises(ValueError, match="steps"):
        contain_motion(g, d, [cam], [mask], steps=(0.5, 0.7))


def test_update_stage_contains_the_trained_motion(tmp_path, scene):
    """`anigs update --masks`: the trained model keeps only Gaussians whose motion stays inside the
    dilated masks; update.json reports the containment; frozen Gaussians are back at the static fit.
    With a round plan, only the final round contains (update.contain_rounds: final)."""
    import json

    from anigs.animate.deform import load_model
    from anigs.animate.frames import render_clip
    from anigs.cli import main
    from anigs.images import write_mask_png
    from anigs.video import save_clip

    g, index, cam, _, mask = scene
    (tmp_path / "static").mkdir()
    g.save_ply(tmp_path / "static" / "canonical.ply")
    (tmp_path / "views").mkdir()
    (tmp_path / "views" / "views.json").write_text(json.dumps({"views": [{"id": "v00", "camera": cam.to_dict()}]}))
    masks = MasksOutputs(tmp_path / "masks")
    write_mask_png(masks.path("mask", view="v00"), mask)
    lifted = _flags(g.num, index["cluster"], index["halo"])
    np.save(masks.path("dynamic"), lifted)
    with torch.no_grad():  # a target in which everything lifted sways strongly
        target = render_clip(g, _deformation(g, lifted, scale=0.3), cam, 9, BG).numpy()
    save_clip(tmp_path / "v00.npz", target, {"camera": cam.to_dict()})
    params = {"steps": 20, "num_bases": 4, "background": list(BG), "lr_position_coeffs": 0.05, "spatial_lr_scale": 1.0}
    base = ["update", "--static", str(tmp_path / "static"), "--targets", str(tmp_path / "v00.npz"),
            "--views", str(tmp_path / "views"), "--masks", str(tmp_path / "masks")]
    assert main(base + ["--out", str(tmp_path / "on"), "--round", "2", "--rounds", "2",
                        "--params", json.dumps(params)]) == 0
    assert main(base + ["--out", str(tmp_path / "off"), "--params", json.dumps({**params, "contain": False})]) == 0
    assert main(base + ["--out", str(tmp_path / "early"), "--round", "1", "--rounds", "2",
                        "--params", json.dumps(params)]) == 0
    c_on, d_on, _ = load_model(tmp_path / "on" / "model.pt", g)
    c_off, d_off, _ = load_model(tmp_path / "off" / "model.pt", g)
    assert d_off.num_dynamic == int(lifted.sum())
    early = json.loads((tmp_path / "early" / "update.json").read_text())
    assert "containment" not in early and early["num_dynamic"] == d_off.num_dynamic
    info = json.loads((tmp_path / "on" / "update.json").read_text())["containment"]
    assert info["frozen"] >= 1 and info["dynamic_after"] == d_on.num_dynamic == d_off.num_dynamic - info["frozen"]
    assert index["halo"] not in set(d_on.dynamic_index.tolist())
    frozen = sorted(set(d_off.dynamic_index.tolist()) - set(d_on.dynamic_index.tolist()))
    assert torch.equal(c_on.means[frozen], g.means[frozen])  # back at the static fit
    with torch.no_grad():
        on = render_clip(c_on, d_on, cam, 9, BG).numpy()
        off = render_clip(c_off, d_off, cam, 9, BG).numpy()
    from anigs.metrics.motion import outside_mask_still

    still_on, still_off = outside_mask_still(on, mask), outside_mask_still(off, mask)
    assert still_on >= 0.995 and still_on > still_off, (still_on, still_off)
    assert np.abs(on - on[:1]).max() > 0.02  # what is left still moves
