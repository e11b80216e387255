"""Far points: started where photos show something SfM did not triangulate, never where SfM points
are or where the photo shows the background colour; deterministic; bounded by their share."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.static.far import far_points, far_radius
from anigs.static.fit import StaticConfig, fit_static

from tests.static.test_fit import make_scene, sfm_points


def _scene():
    gt, cams, imgs = make_scene(n_cams=8, width=64, height=48)
    return gt, cams, [im.numpy() for im in imgs]


def test_far_points_fill_only_what_sfm_left_out():
    gt, cams, imgs = _scene()
    p, _ = sfm_points(gt, every=1, noise=0.0)
    black = (0.0, 0.0, 0.0)
    # the scene's renders show the black background around the wall and ground: nothing to add there
    fp, fc = far_points(p, cams, imgs, black, 1000)
    assert len(fp) == 0
    # the same photos over a blue sky: the sky cells get far points, on the far sphere, coloured blue
    sky = np.array([0.3, 0.5, 0.9], np.float32)
    skied = [np.where(im.sum(-1, keepdims=True) < 1e-3, sky, im) for im in imgs]
    fp, fc = far_points(p, cams, skied, black, 1000)
    assert 0 < len(fp) <= 1000
    mid, radius = far_radius(p, cams)
    assert np.allclose(np.linalg.norm(fp - mid, axis=1), radius, rtol=1e-6)
    off = np.abs(fc - sky).max(1)
    assert np.mean(off < 0.05) > 0.7  # sky cells (cells at the wall's edge mix in its colour)
    fp2, _ = far_points(p, cams, skied, black, 1000)
    assert np.array_equal(fp, fp2)  # deterministic
    assert len(far_points(p, cams, skied, black, 5)[0]) == 5  # thinned to the limit
    # with the sky as the background colour only cells mixing sky and wall remain
    assert len(far_points(p, cams, skied, tuple(sky), 1000)[0]) < 0.1 * len(fp)


def _sky_scene(sky: tuple[float, float, float]):
    """The wall-and-ground scene's photos over a sky colour (its black background replaced), cameras
    and pseudo-SfM points."""
    gt, cams, imgs = make_scene(n_cams=12, width=48, height=36)
    skied = [torch.where(im.sum(-1, keepdim=True) < 1e-3, torch.tensor(sky), im) for im in imgs]
    return skied, cams, *sfm_points(gt, every=3)


def test_fit_with_far_points_over_a_sky():
    skied, cams, p, c = _sky_scene((0.3, 0.5, 0.9))
    fast = {"iterations": 60, "eval_every": 0, "sh_degree": 0, "densify": {"start": 20, "stop": 40, "every": 20}}
    _, with_far = fit_static(skied, cams, p, c, StaticConfig.from_dict(fast), progress=False)
    _, without = fit_static(skied, cams, p, c, StaticConfig.from_dict({**fast, "far_share": 0.0}), progress=False)
    assert with_far["far_points"] > 0 and without["far_points"] == 0
    assert with_far["train_psnr"] > without["train_psnr"] + 1.0  # the sky is there from the start


def test_random_background_makes_what_the_photos_show_opaque():
    from anigs.render import render_gaussians

    skied, cams, p, c = _sky_scene((0.3, 0.5, 0.9))
    fast = {"iterations": 150, "eval_every": 0, "sh_degree": 0, "densify": {"start": 20, "stop": 100, "every": 20}}
    alpha = {}
    for bg in ("random", [0.3, 0.5, 0.9]):
        g, _ = fit_static(skied, cams, p, c, StaticConfig.from_dict({**fast, "background": bg}), progress=False)
        with torch.no_grad():
            alpha[str(bg)] = float(torch.stack([render_gaussians(g, cam)[1].mean() for cam in cams]).mean())
    # trained over a fixed sky colour the sky may stay transparent; over random colours it cannot
    assert alpha["random"] > 0.85 and alpha["random"] > alpha[str([0.3, 0.5, 0.9])] + 0.2, alpha
    with pytest.raises(ValueError, match="static.background"):
        StaticConfig.from_dict({"background": "sky"})
