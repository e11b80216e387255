"""A flowering plant's blossoms sway with it when the prompt names the plant but no flowers (rule 5 of
anigs.effects.rules.blossoms, ``effects.rules.blossoms.with_plants``).

On the street capture the prompt "a street with potted plants, shrubs and climbing plants" named no
flowers, so the yellow climbing rose's blossoms stayed still while its leaves swayed (its mark in
12.jpg: 0.27 of it inside the photo's masks).
"""
from __future__ import annotations

import numpy as np
import torch

from anigs.effects import EffectsConfig, detect_effects
from anigs.effects.config import REGIONS
from anigs.effects.rules import check_candidates
from anigs.synth import render_image
from anigs.synth.scene import SKY
from tests.effects.test_decoys import _chosen
from tests.effects.test_effects import bush_with_a_blossom

FOLIAGE, FLOWERS = REGIONS.index("foliage"), REGIONS.index("flowers")
RED, GREEN = (0.9, 0.2, 0.3), (0.2, 0.55, 0.15)


def test_a_shrubs_blossom_sways_with_it_when_the_prompt_names_only_plants():
    g, cams, imgs = bush_with_a_blossom()
    labels = g.extras["label"].numpy()
    blossom, leaf = labels == 2, labels == 1
    res = detect_effects(imgs, cams, g, EffectsConfig(), kinds=["foliage"])
    foliage = _chosen(res, "foliage_sway")
    print(f"blossom in foliage {foliage[blossom].mean():.3f}, leaves {foliage[leaf].mean():.3f}")
    assert not res.effects["flower_bob"].detected
    assert "the prompt names none; blossoms on the foliage it names sway with it" in res.effects["flower_bob"].reason
    assert foliage[blossom].mean() >= 0.6 and foliage[leaf].mean() >= 0.7
    moved = [c for c in res.candidates if c.rule == "blossoms"]
    assert moved and all(c.moved_to == "foliage" and c.region == "flowers" for c in moved)
    assert all("sway with their plant" in c.reason for c in moved)
    # the photos' foliage masks take the blossom's pixels
    assert not any(m.any() for m in res.effects["flower_bob"].masks)
    # switched off, the blossom stays still
    off = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"rules": {"blossoms": {"with_plants": False}}}), kinds=["foliage"])
    assert _chosen(off, "foliage_sway")[blossom].mean() <= 0.1
    assert not [c for c in off.candidates if c.region == "flowers"]
    assert "not looked for, the prompt does not name it" in off.effects["flower_bob"].reason


def _ball(rng, centre, radius: float, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    return np.asarray(centre) + d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.6, 1.0, (n, 1)) * radius


def test_only_blossoms_the_named_plants_hold_join_them():
    """Rules level: blossoms on a bush join its foliage; a bed of flowers on a lawn far from any bush stays
    still and is not listed; without ``blossoms_of`` both stay flowers."""
    rng = np.random.default_rng(0)
    bush = _ball(rng, (0, 0, 1.0), 0.6, 600)
    on_bush = _ball(rng, (0, -0.55, 1.1), 0.12, 60)
    grass = np.column_stack([rng.uniform(3, 5, (400, 2)), rng.uniform(0, 0.05, 400)])
    bed = np.column_stack([rng.uniform(3.6, 4.2, (80, 2)), rng.uniform(0.05, 0.5, 80)])
    means = np.vstack([bush, on_bush, grass, bed])
    region = np.concatenate([np.full(600, FOLIAGE), np.full(60, FLOWERS), np.full(400, REGIONS.index("grass")),
                             np.full(80, FLOWERS)])
    colours = np.vstack([np.tile(GREEN, (600, 1)), np.tile(RED, (60, 1)), np.tile(GREEN, (400, 1)),
                         np.tile(RED, (80, 1))])
    height = means[:, 2]
    out, cands, _ = check_candidates(means, colours, region, height, 1.6, 0.25, EffectsConfig(), None, blossoms_of="foliage")
    assert (out[600:660] == FOLIAGE).all()
    assert (out[1060:] == -1).all()
    flowers = [c for c in cands if c.region == "flowers"]
    assert len(flowers) == 1 and flowers[0].moved_to == "foliage" and flowers[0].rule == "blossoms"
    assert flowers[0].figures["on_plants"] >= 0.9
    plain, cands, _ = check_candidates(means, colours, region, height, 1.6, 0.25, EffectsConfig(), None)
    assert (plain[600:660] == FLOWERS).all() and (plain[1060:] == FLOWERS).all()
    assert not [c for c in cands if c.rule == "blossoms"]


def test_a_bush_without_blossoms_says_none_were_found():
    g, cams, _ = bush_with_a_blossom()
    bare = g.subset(torch.from_numpy(np.flatnonzero(g.extras["label"].numpy() != 2)))
    imgs = [render_image(bare, c, SKY) for c in cams]
    res = detect_effects(imgs, cams, bare, EffectsConfig(), kinds=["foliage"])
    assert res.effects["foliage_sway"].detected
    assert not [c for c in res.candidates if c.rule == "blossoms"]
    assert "the prompt names none; no blossoms were found on the foliage it names" in res.effects["flower_bob"].reason


def test_blossoms_do_not_make_their_plant_be_there():
    """Blossoms moved onto the named plants sway with them, but only count as the plant's own Gaussians for
    moving, not for whether the plant is there (``decide``): a foliage region that falls short of
    ``decide.min_gaussians`` on its own stays still, blossoms and all. On the courtyard capture 24 blue
    Gaussians on a green bin (a sticker, taken for a blossom) lifted the bins' 0.1% of foliage Gaussians over
    the bar under every prompt that named trees and no flowers (the bin mark in 0000.jpg 36-39% moving)."""
    g, cams, imgs = bush_with_a_blossom()
    res = detect_effects(imgs, cams, g, EffectsConfig(), kinds=["foliage"])
    carried = sum(len(c.indices) for c in res.candidates if c.rule == "blossoms" and c.moved_to == "foliage")
    total = int(_chosen(res, "foliage_sway").sum())
    assert carried > 0 and res.effects["foliage_sway"].detected
    between = {"decide": {"min_gaussians": total - carried + 1}}  # enough with the blossoms, too few without
    short = detect_effects(imgs, cams, g, EffectsConfig.from_dict(between), kinds=["foliage"])
    assert not short.effects["foliage_sway"].detected
    assert not _chosen(short, "foliage_sway").any()
    assert f"Not counted: the {carried} Gaussians of blossoms moved onto it" in short.effects["foliage_sway"].reason
    assert f"blossoms were found on the foliage it names ({carried} Gaussians), which is not there, so they stay still" \
        in short.effects["flower_bob"].reason
