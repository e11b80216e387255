"""Rule ``made_surface`` (anigs.effects.rules.made_surface): smooth surfaces that close around a volume are made
things, whatever their colour; leaves, a fit's volume of coherent splats and one flat sheet are not. Blossoms
attach only to foliage that survived every rule, and the rules measure heights without a trusted ground plane."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.effects.config import EffectsConfig
from anigs.effects.detect import flattest_axes
from anigs.effects.geometry import scene_ground
from anigs.effects.kinds import REGIONS
from anigs.effects.rules import Candidate, Context, check_candidates
from anigs.effects.rules.made_surface import MadeSurface, surface_figures
from anigs.synth.scene import Builder, assemble

FOLIAGE, FLOWERS = REGIONS.index("foliage"), REGIONS.index("flowers")


def _parts(build) -> tuple[np.ndarray, np.ndarray]:
    """(centres [N,3], unit flattest axes [N,3]) of the Gaussians ``build(B)`` adds."""
    B = Builder(np.random.default_rng(0), 1.0)
    build(B)
    g = assemble(B.parts)
    return g.means.double().numpy(), flattest_axes(g)


def _paint(p: np.ndarray) -> np.ndarray:
    return np.tile([0.1, 0.45, 0.12], (len(p), 1))


def _ctx(means: np.ndarray, flattest: np.ndarray, region: int = FOLIAGE) -> Context:
    return Context(means, np.full((len(means), 3), 0.4), np.full(len(means), region), None, 1.0, 0.3, 0.3,
                   EffectsConfig().regions.bands(), flattest=flattest)


def _verdict(means: np.ndarray, flattest: np.ndarray):
    cand = Candidate(1, "foliage", np.arange(len(means)), means.mean(0), 1.0)
    return MadeSurface().check(cand, _ctx(means, flattest)), cand.figures


@pytest.mark.parametrize("what", ["box", "pillar"])
def test_a_painted_box_or_pillar_is_a_made_surface(what):
    if what == "box":  # a wheelie bin's body: five faces, coarsely sampled as a fit far away would be
        means, flat = _parts(lambda B: B.box((0, 0, 0.55), (0.6, 0.7, 1.1), 0.3, 0.1, _paint, "clutter"))
    else:
        means, flat = _parts(lambda B: B.cylinder((0, 0, 0), (0, 0, 3.0), 0.22, 0.22, 0.12, _paint, "building"))
    verdict, fig = _verdict(means, flat)
    assert verdict is not None and verdict.rule == "made_surface", fig
    assert fig["smooth"] >= 0.7 and fig["turning"] >= 0.25, fig
    assert "smooth closed surface, not leaves" in verdict.reason


def test_leaves_are_not_a_made_surface():
    means, flat = _parts(lambda B: B.blob([((0, 0, 1.0), (0.5, 0.5, 0.5))], 1500, (0.2, 0.42, 0.12), "foliage",
                                          (0, 0, 0.3), 0.05))
    verdict, fig = _verdict(means, flat)
    assert verdict is None and fig["smooth"] < 0.2, fig


def test_a_fits_volume_of_splats_that_all_face_the_camera_is_not_a_made_surface():
    """A real fit's crown: centres spread through a volume, splats turned towards the cameras (their normals
    agree, as on the real captures), so neighbours do not continue each other's plane."""
    rng = np.random.default_rng(1)
    means = rng.normal(size=(1500, 3)) * [0.5, 0.5, 0.4]
    flat = np.tile([0.0, 1.0, 0.0], (1500, 1)) + rng.normal(scale=0.25, size=(1500, 3))
    flat /= np.linalg.norm(flat, axis=1, keepdims=True)
    verdict, fig = _verdict(means, flat)
    assert verdict is None and fig["smooth"] < MadeSurface().min_smooth, fig


def test_one_flat_sheet_is_left_to_the_plane_rule():
    """Smooth, but it does not turn: a wall or a fit's flattened leaves, not a closed surface."""
    means, flat = _parts(lambda B: B.surface((0, 0, 0), (1, 0, 0), (0, 0, 1), (2.0, 1.5), (0.05, 0.05), _paint,
                                             "building"))
    verdict, fig = _verdict(means, flat)
    assert verdict is None and fig["smooth"] > 0.9 and fig["turning"] < 0.05, fig


def test_the_figures_do_not_depend_on_the_order_of_the_gaussians():
    means, flat = _parts(lambda B: B.box((0, 0, 0.5), (0.8, 0.5, 0.5), 0.0, 0.06, _paint, "clutter"))
    perm = np.random.default_rng(2).permutation(len(means))
    a = surface_figures(means, flat, 8, 60.0, 10.0, 0.5)
    b = surface_figures(means[perm], flat[perm], 8, 60.0, 10.0, 0.5)
    assert a == pytest.approx(b)


def test_blossoms_attach_only_to_foliage_every_rule_kept():
    """A red sticker on a green bin: the bin is chosen as foliage and stilled as a made surface, so the sticker
    is no blossom on it (before, the blossoms rule moved it with the bin)."""
    bin_means, bin_flat = _parts(lambda B: B.box((0, 0, 0.55), (0.6, 0.7, 1.1), 0.0, 0.05, _paint, "clutter"))
    rng = np.random.default_rng(3)
    sticker = np.column_stack([rng.uniform(-0.1, 0.1, 40), np.full(40, -0.36), rng.uniform(0.6, 0.8, 40)])
    means = np.concatenate([bin_means, sticker])
    flattest = np.concatenate([bin_flat, np.tile([0.0, 1.0, 0.0], (40, 1))])
    region = np.concatenate([np.full(len(bin_means), FOLIAGE), np.full(40, FLOWERS)])
    colours = np.concatenate([np.tile([0.1, 0.45, 0.12], (len(bin_means), 1)), np.tile([0.85, 0.1, 0.1], (40, 1))])
    out = check_candidates(means, colours, region, None, 1.0, 0.3, EffectsConfig(), blossoms_of="foliage",
                           flattest=flattest)
    assert (out.region_of == -1).all(), np.unique(out.region_of, return_counts=True)
    rules = {c.region: c.rule for c in out.candidates}
    assert rules["foliage"] == "made_surface"
    assert all(c.moved_to != "foliage" for c in out.candidates)


def test_without_a_trusted_ground_the_rules_measure_heights_from_the_lowest_layer():
    """A yard seen from standing height: the paving is too small a share of the Gaussians to be trusted as the
    ground (grass and water are not looked for), but the rules still get heights (every rule runs)."""
    from anigs.cameras import intrinsics_from_fov, look_at, Camera

    rng = np.random.default_rng(4)
    paving = np.column_stack([rng.uniform(-5, 5, 200), rng.uniform(-5, 5, 200), rng.normal(0, 0.005, 200)])
    walls = np.column_stack([rng.uniform(-5, 5, 9800), np.full(9800, 5.0), rng.uniform(0.5, 8, 9800)])
    means = np.concatenate([paving, walls])
    K = intrinsics_from_fov(60, 160, 120)
    cams = [Camera(K, look_at(np.array([x, -4.0, 1.6]), np.array([0.0, 5, 2])), 160, 120, f"c{x}") for x in (-1, 1)]
    ground = scene_ground(means, cams, np.array([0.0, 0, 1]), 0.03, 0.03)
    assert ground.plane is None and "ground uncertain" in ground.note
    assert ground.reference is ground.estimate and abs(ground.reference.offset) < 0.05
    assert "estimate" in ground.to_dict()
