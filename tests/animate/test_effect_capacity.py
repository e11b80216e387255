"""Per-effect capacity (``update.effect_num_bases``): masked DCT bases stay zero, survive
save/load/remap/containment copies, the default {} changes nothing, bad keys are refused."""
from __future__ import annotations

import io

import pytest
import torch

from anigs.animate.deform import DCTDeformation, load_model, save_model
from anigs.animate.frames import render_clip
from anigs.animate.config import UpdateConfig
from anigs.animate.update import ViewData, bases_from_config, run_update
from anigs.effects.labels import effect_label_ids
from tests._scenes import ring_cameras, sway_motion, sway_scene

pytestmark = pytest.mark.usefixtures("one_thread")

K = 4


def _problem(T: int = 9):
    """Shrub scene with int labels: 20 dynamic Gaussians labelled 1 (foliage), 20 labelled 2 (grass)."""
    G, mask = sway_scene(n_dyn=40, grid=6, anisotropic=True)
    gt = sway_motion(G, mask, T, K=3, amplitude=0.08)
    views = []
    for c in ring_cameras(2, 48, 36):
        clip = render_clip(G, gt, c, T)
        views.append(ViewData(c, clip, clip[0]))
    labels = mask.long()
    dyn = mask.nonzero()[:, 0]
    labels[dyn[20:]] = 2
    return G, labels, views


def _run(G, labels, views, **kw):
    cfg = UpdateConfig(steps=6, num_bases=K, lr_position_coeffs=0.05, seed=0, **kw)
    return run_update(G, labels, views, cfg, progress=False)


def test_masked_bases_are_zero_after_training_and_the_others_train():
    G, labels, views = _problem()
    res = _run(G, labels, views, effect_num_bases={"grass_wave": 2})  # label 2 -> first 2 bases
    d = res.deformation
    grass = labels[d.dynamic_index] == 2
    assert d.active_bases.tolist() == [K if not g else 2 for g in grass.tolist()]
    for c in (d.pos_coeffs, d.rot_coeffs):
        assert bool((c[grass][:, :, 2:] == 0).all())  # masked: exactly zero
        assert c[grass][:, :, :2].abs().max() > 0 and c[~grass][:, :, 2:].abs().max() > 0


def test_default_is_unchanged_and_a_full_capacity_mask_is_bitwise_the_same():
    G, labels, views = _problem()
    plain = _run(G, labels, views, effect_num_bases={})
    assert plain.deformation.active_bases is None
    assert "active_bases" not in plain.deformation.state()  # model.pt holds what it held before the key
    assert "effect_num_bases" not in UpdateConfig(effect_num_bases={}).to_dict()
    assert UpdateConfig().effect_num_bases == {"grass_wave": 6, "flower_bob": 6}  # the measured default
    full = _run(G, labels, views, effect_num_bases={"1": K, "2": K})
    assert torch.equal(full.deformation.pos_coeffs, plain.deformation.pos_coeffs)
    assert torch.equal(full.deformation.rot_coeffs, plain.deformation.rot_coeffs)
    assert torch.equal(full.canonical.means, plain.canonical.means)


def test_save_load_remap_and_state_copies_keep_the_capacity(tmp_path):
    G, labels, views = _problem()
    res = _run(G, labels, views, effect_num_bases={"2": 1})
    d = res.deformation
    path = tmp_path / "model.pt"
    save_model(path, d, res.canonical, UpdateConfig(num_bases=K, effect_num_bases={"2": 1}).to_dict())
    _, d2, payload = load_model(path)
    assert payload["config"]["effect_num_bases"] == {"2": 1}
    assert torch.equal(d2.active_bases, d.active_bases)
    assert torch.equal(d2.pos_coeffs, d.pos_coeffs) and torch.equal(d2.rot_coeffs, d.rot_coeffs)
    for t in (0, 3.5, 8):
        a, b = d.offsets(t), d2.offsets(t)
        assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    # the containment's copies: remapped (a subset stays dynamic) and from_state (scaled motion)
    keep = d.dynamic_index[::2]
    r = d.remapped(keep)
    assert torch.equal(r.active_bases, d.active_bases[::2]) and torch.equal(r.pos_coeffs, d.pos_coeffs[::2])
    grown = d.remapped(torch.cat([d.dynamic_index, torch.tensor([0])]))  # a new Gaussian: all K
    assert grown.active_bases[-1] == K
    from anigs.masks.contain import scaled_motion

    half = scaled_motion(d, torch.full((d.num_dynamic,), 0.5).numpy())
    assert torch.equal(half.active_bases, d.active_bases) and torch.equal(half.pos_coeffs, d.pos_coeffs * 0.5)
    # training a remapped (round r+1) model keeps masked bases at zero, without a mask it frees them
    again = run_update(res.canonical, labels, views, UpdateConfig(steps=3, num_bases=K, seed=1,
                       effect_num_bases={"2": 1}), init=d2, progress=False)
    grass = labels[again.deformation.dynamic_index] == 2
    assert bool((again.deformation.pos_coeffs[grass][:, :, 1:] == 0).all())
    free = run_update(res.canonical, labels, views, UpdateConfig(steps=3, num_bases=K, seed=1, effect_num_bases={}),
                      init=d2, progress=False)
    assert free.deformation.active_bases is None


def test_a_capacity_applied_to_a_trained_field_truncates_it():
    d = DCTDeformation(torch.arange(3), 9, K, rotation=False)
    with torch.no_grad():
        d.pos_coeffs.fill_(1.0)
    d.set_active_bases(torch.tensor([0, 2, K]))
    assert d.pos_coeffs.sum(dim=(1, 2)).tolist() == [0.0, 6.0, 12.0]
    assert torch.equal(d.offsets(2)[0][0], torch.zeros(3))
    with pytest.raises(ValueError, match="active_bases must be in"):
        d.set_active_bases(torch.tensor([0, 1, K + 1]))
    with pytest.raises(ValueError, match="active_bases must be"):
        d.set_active_bases(torch.tensor([1, 2]))


def test_effect_names_map_to_labels_and_shared_labels_take_the_largest():
    labels = effect_label_ids()
    assert labels["foliage_sway"] == labels["leaf_flutter"] == 1 and labels["grass_wave"] == 2
    assert labels["flower_bob"] == 3
    mask = torch.tensor([0, 1, 2, 3, 4, 0])
    cfg = UpdateConfig.from_dict({"num_bases": 12, "effect_num_bases": {"foliage_sway": 4, "grass_wave": 6}})
    assert bases_from_config(mask, cfg, 12).tolist() == [12, 6, 12, 12]  # foliage also flutters: 12
    cfg = UpdateConfig.from_dict({"num_bases": 12, "effect_num_bases": {"foliage_sway": 4, "leaf_flutter": 8}})
    assert bases_from_config(mask, cfg, 12).tolist() == [8, 12, 12, 12]
    assert bases_from_config(mask, cfg, 6).tolist() == [6, 6, 6, 6]  # clamped to the resolved K
    assert bases_from_config(mask, UpdateConfig(effect_num_bases={}), 12) is None
    boolean = mask > 0
    assert bases_from_config(boolean, UpdateConfig(num_bases=12, effect_num_bases={"1": 5}), 12).tolist() == [5] * 4
    # effect names without per-Gaussian labels: every Gaussian keeps num_bases (warned), labels still apply
    assert bases_from_config(boolean, cfg, 12) is None
    mixed = UpdateConfig.from_dict({"num_bases": 12, "effect_num_bases": {"grass_wave": 6, "1": 5}})
    assert bases_from_config(boolean, mixed, 12).tolist() == [5] * 4


@pytest.mark.parametrize("bad, err, match", [
    ({"foliage": 3}, KeyError, r"effect_num_bases key 'foliage' is unknown"),
    ({"0": 3}, KeyError, r"effect_num_bases key '0' is unknown"),
    ({"grass_wave": -2}, ValueError, r"effect_num_bases\['grass_wave'\] = -2: must be an integer >= 1"),
    ({"1": 0}, ValueError, r"effect_num_bases\['1'\] = 0"),
    ({"1": 2.5}, ValueError, r"effect_num_bases\['1'\] = 2.5"),
    ({"1": 3, "leaf_flutter": 4}, ValueError, r"label\(s\) \[1\] both by number and by effect name"),
])
def test_config_refuses_bad_capacities_naming_the_key(bad, err, match):
    with pytest.raises(err, match=match):
        UpdateConfig.from_dict({"num_bases": 12, "effect_num_bases": bad})


def test_model_bytes_without_the_key_do_not_depend_on_it(tmp_path):
    """A field without ``active_bases`` writes the checkpoint it wrote before the key existed (same
    payload keys), so the default {} gives byte-identical model.pt files."""
    d = DCTDeformation(torch.arange(3), 9, K)
    G, _ = sway_scene(n_dyn=3, grid=2)
    d.num_gaussians = G.num
    buf = io.BytesIO()
    torch.save(d.state(), buf)
    assert set(d.state()) == {"num_frames", "num_bases", "rotation", "num_gaussians", "dynamic_index",
                              "pos_coeffs", "rot_coeffs", "max_offset", "max_angle"}
    save_model(tmp_path / "a.pt", d, G, UpdateConfig().to_dict())
    save_model(tmp_path / "b.pt", DCTDeformation.from_state(d.state()), G, UpdateConfig().to_dict())
    assert (tmp_path / "a.pt").read_bytes() == (tmp_path / "b.pt").read_bytes()


def test_update_stage_reads_effect_labels_and_refuses_labels_that_disagree(tmp_path, caplog):
    """`anigs update --masks`: the masks stage's int labels (effect_labels.npy) drive the per-effect
    capacity; labels that do not mark exactly its dynamic set are an error naming the file."""
    import json

    import numpy as np

    from anigs.cli import main
    from anigs.video import save_clip

    G, labels, views = _problem()
    (tmp_path / "static").mkdir()
    G.save_ply(tmp_path / "static" / "canonical.ply")
    for name in ("masks", "bad"):
        (tmp_path / name).mkdir()
        np.save(tmp_path / name / "dynamic.npy", (labels > 0).numpy())
    np.save(tmp_path / "masks" / "effect_labels.npy", labels.numpy().astype(np.int8))
    for k, v in enumerate(views):
        save_clip(tmp_path / f"v{k}.npz", v.clip.numpy(), {"camera": v.camera.to_dict()})
    params = {"steps": 6, "num_bases": K, "lr_position_coeffs": 0.05, "effect_num_bases": {"grass_wave": 2},
              "contain": False}
    base = ["update", "--static", str(tmp_path / "static"), "--targets",
            *[str(tmp_path / f"v{k}.npz") for k in range(len(views))], "--params", json.dumps(params)]
    assert main(base + ["--masks", str(tmp_path / "masks"), "--out", str(tmp_path / "m")]) == 0
    _, d, _ = load_model(tmp_path / "m" / "model.pt", G)
    grass = (labels[d.dynamic_index] == 2)
    assert grass.any() and bool((d.pos_coeffs[grass][:, :, 2:] == 0).all())
    assert bool((d.pos_coeffs[~grass][:, :, 2:] != 0).any())
    bad = labels.clone()
    bad[(labels == 0).nonzero()[0, 0]] = 1  # a static Gaussian labelled
    np.save(tmp_path / "bad" / "effect_labels.npy", bad.numpy().astype(np.int8))
    assert main(base + ["--masks", str(tmp_path / "bad"), "--out", str(tmp_path / "x")]) != 0
    assert "effect_labels.npy (effect labels" in caplog.text and "re-run the masks stage" in caplog.text
    assert not (tmp_path / "x" / "model.pt").exists()
