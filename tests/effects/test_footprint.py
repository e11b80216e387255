"""A Gaussian joins a region only where its footprint agrees, over all the photos (``effects.lift.footprint_share``)
and in the photos that show it (``photo_min_share``, ``photo_vetoes``), and vegetation
colour needs a chroma above noise (``effects.regions.green_min_chroma``).

On the street walk (a 15 dB fit) blurred splats centred on a bush reached over a green gate and the
facades: their centres voted foliage, so 18% of the gate moved; the flower capture's dark mossy stones
had a green cast of a few levels, so their splats moved too. The garden here gets one such smear: a
wide splat centred on a bush, over what the photos show around it.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.effects import REGIONS, EffectsConfig, detect_effects
from anigs.effects import cues
from anigs.gaussians import Gaussians
from anigs.synth import SceneConfig

from test_effects import _capture

FOLIAGE = REGIONS.index("foliage")


@pytest.fixture(scope="module")
def smeared():
    """The garden's photos, and its model with a wide, half-transparent splat (the last one) centred on
    the foliage Gaussian farthest out from the foliage's middle, 40 x its size: what a blurry fit puts
    over a bush's edge and the wall or the lawn beside it."""
    g, cams, imgs = _capture(SceneConfig(), images=8, width=128)
    res = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}}))
    fol = np.flatnonzero(res.region_of == FOLIAGE)
    centre = g.means[fol].median(0).values
    near = fol[int(torch.linalg.norm(g.means[fol] - centre, dim=1).argmax())]
    smear = g.subset(torch.tensor([near]))
    smear = Gaussians(smear.means, smear.quats, smear.log_scales + np.log(40.0), torch.full_like(smear.opacity_logits, 0.0),
                      smear.sh, {k: v for k, v in smear.extras.items()})
    return Gaussians.concat([g, smear]), cams, imgs, res


def test_a_smear_centred_on_a_bush_stays_still_while_the_bush_sways(smeared):
    g, cams, imgs, before = smeared
    off = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}, "lift": {
        "footprint_share": 0.0, "photo_min_share": 0.0}}))
    assert off.region_of[-1] == FOLIAGE  # its centre votes foliage: without the footprint it would move
    on = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}}))
    assert on.region_of[-1] == -1
    alone = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}, "lift": {
        "photo_min_share": 0.0}}))
    assert alone.region_of[-1] == -1  # the summed footprint alone keeps it still
    kept = (on.region_of[:-1] == FOLIAGE) & (before.region_of == FOLIAGE)
    assert kept.sum() >= 0.9 * (before.region_of == FOLIAGE).sum()  # the bush's own Gaussians still sway
    assert on.effects["foliage_sway"].detected


def test_dark_pixels_with_a_faint_green_cast_are_no_vegetation():
    stone = [0.10, 0.12, 0.09]  # chroma 0.03: a mossy stone in shadow (hue green, saturation 0.25)
    leaf = [0.05, 0.15, 0.04]   # chroma 0.11: a shaded leaf
    img = np.array([[stone, leaf]], np.float32)
    cfg = EffectsConfig()
    args = (img, cfg.regions.green_hue, cfg.regions.green_min_saturation, cfg.regions.min_value)
    assert cues.green(*args, 0.0).tolist() == [[True, True]]
    assert cues.green(*args, cfg.regions.green_min_chroma).tolist() == [[False, True]]


def test_footprint_and_chroma_settings_are_checked():
    with pytest.raises(ValueError, match="footprint_share"):
        EffectsConfig.from_dict({"lift": {"footprint_share": 1.5}})
    with pytest.raises(ValueError, match="footprint_reach_px"):
        EffectsConfig.from_dict({"lift": {"footprint_reach_px": -1}})


def _one_splat_photos(mask_on_it: list[bool], size: int = 48):
    """One splat at the origin seen by cameras around it; each photo's foliage mask covers the splat or the
    opposite corner (``mask_on_it`` per photo). Returns the splat, the photos' maps and regions."""
    from types import SimpleNamespace

    from anigs.cameras import Camera, intrinsics_from_fov, look_at

    g = Gaussians.from_points(torch.zeros(1, 3), torch.tensor([[0.2, 0.6, 0.2]]), scales=0.15, opacity=0.9)
    K = intrinsics_from_fov(60, size, size)
    maps, regions = [], []
    for k, on in enumerate(mask_on_it):
        a = 2 * np.pi * k / len(mask_on_it)
        cam = Camera(K, look_at([3 * np.cos(a), 3 * np.sin(a), 0.5], [0, 0, 0]), size, size)
        fol = np.zeros((size, size), bool)
        if on:
            fol[size // 4:3 * size // 4, size // 4:3 * size // 4] = True
        else:
            fol[:size // 8, :size // 8] = True
        masks = {name: (fol if name == "foliage" else np.zeros_like(fol)) for name in REGIONS}
        maps.append(SimpleNamespace(camera=cam))
        regions.append(SimpleNamespace(masks=masks))
    return g, maps, regions


def test_the_photos_that_show_a_splat_off_its_region_have_a_say():
    """Four photos see the splat on the plant, two see it off the plant: the summed share (4/6) keeps it, the
    two photos' shares (0) do not (``effects.lift.photo_min_share``, ``photo_vetoes``: the street's facade was
    painted by such splats in the photos that show them off the bushes). One photo alone (its masks may have
    missed the plant) vetoes only with ``photo_vetoes: 1``."""
    from anigs.effects.config import LiftConfig
    from anigs.effects.lift import footprint_agrees, footprint_shares

    region = np.array([FOLIAGE])
    g, maps, regions = _one_splat_photos([True, True, False, True, True, False])
    foot, least = footprint_shares(g, maps, regions, reach=2, least_k=2)
    assert foot[0, FOLIAGE] == pytest.approx(4 / 6, abs=0.01)
    assert least[0, FOLIAGE].tolist() == pytest.approx([0.0, 0.0], abs=0.01)
    assert not footprint_agrees(foot, least, region, LiftConfig())[0]
    assert footprint_agrees(foot, least, region, LiftConfig(photo_min_share=0.0))[0]
    g, maps, regions = _one_splat_photos([True, True, True, False])
    foot, least = footprint_shares(g, maps, regions, reach=2, least_k=2)
    assert least[0, FOLIAGE, 0] == pytest.approx(0.0, abs=0.01) and least[0, FOLIAGE, 1] > 0.95
    assert footprint_agrees(foot, least, region, LiftConfig())[0]  # one photo's say is not enough by default
    assert not footprint_agrees(foot, least, region, LiftConfig(photo_vetoes=1))[0]
    g, maps, regions = _one_splat_photos([True] * 4)
    foot, least = footprint_shares(g, maps, regions, reach=2, least_k=2)
    assert (least[0, FOLIAGE] > 0.95).all() and footprint_agrees(foot, least, region, LiftConfig())[0]


def test_a_photo_where_the_splat_barely_shows_has_no_say():
    """A photo where the splat carries less than PHOTO_MIN_WEIGHT px of weight does not count."""
    from anigs.effects.lift import footprint_shares

    g, maps, regions = _one_splat_photos([True, True, True, False])
    foot, least = footprint_shares(g, maps, regions, reach=2, min_weight=1e9, least_k=2)
    assert (least[0, FOLIAGE] == 1.0).all()


def test_photo_min_share_is_checked():
    with pytest.raises(ValueError, match="photo_min_share"):
        EffectsConfig.from_dict({"lift": {"photo_min_share": -0.1}})
    with pytest.raises(ValueError, match="photo_vetoes"):
        EffectsConfig.from_dict({"lift": {"photo_vetoes": 0}})
