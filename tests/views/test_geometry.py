"""Up direction, ground plane and capture layout (anigs.geometry) on synthetic captures with ground truth.

The scene is the embedded garden (z up, ground z=0); the capture layouts come from
anigs.synth.capture (walk, forward-facing flower bed close-up, orbit around a tree, a walk
looking up at the facade), optionally with photos stored sideways (``roll``). The point cloud
is what the capture observes: the Gaussian centres inside >= 2 camera frusta.
"""
from __future__ import annotations

import logging

import numpy as np
import pytest

from anigs import geometry
from anigs.geometry import angle_deg, classify_layout, estimate_ground, estimate_up, observed_points
from anigs.synth.capture import CameraPathConfig, camera_path
from anigs.synth.build import build_scene
from anigs.synth.scene import LABEL_IDS, SceneConfig

Z = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def garden():
    g = build_scene(SceneConfig(num_gaussians=6000), 0)
    return g.means.numpy().astype(np.float64), g.extras["label"].numpy()


def capture(layout: str, roll: str = "none", n: int = 20):
    return camera_path(CameraPathConfig(layout=layout, roll=roll, num_images=n), 0)


def seen(points: np.ndarray, cams) -> np.ndarray:
    return points[observed_points(points, cams)]


@pytest.mark.parametrize("layout,kind", [("walk", "walk"), ("forward", "forward"), ("orbit", "orbit"),
                                         ("facade", "forward")])
def test_layout_classification(garden, layout, kind):
    pts, _ = garden
    cams = capture(layout)
    lay = classify_layout(cams, Z, seen(pts, cams))
    assert lay.kind == kind, lay.metrics
    assert (lay.focus is None) == (kind == "walk")


def test_orbit_needs_an_object_at_the_focus(garden):
    """The demo's loop also looks inwards, at an open lawn: without the tree it is no orbit."""
    pts, lab = garden
    cams = capture("orbit")
    tx, ty = cams[0].center[:2] * 0 + np.array([4.6, 1.4])
    far = np.hypot(pts[:, 0] - tx, pts[:, 1] - ty) > 2.0  # remove everything near the tree
    assert classify_layout(cams, Z, seen(pts, cams)).kind == "orbit"
    assert classify_layout(cams, Z, seen(pts[far], cams)).kind == "walk"


@pytest.mark.parametrize("layout,roll,bound", [
    ("walk", "none", 3.0), ("walk", "portrait", 3.0), ("walk", "mixed", 3.0),
    ("orbit", "portrait", 3.0), ("orbit", "mixed", 3.0),
    ("facade", "none", 3.0), ("facade", "mixed", 3.0),   # looking up at a building
    ("forward", "none", 5.0),
])
def test_up_in_hard_cases(garden, layout, roll, bound):
    pts, _ = garden
    cams = capture(layout, roll)
    est = estimate_up(cams, seen(pts, cams))
    assert not est.fallback
    assert angle_deg(est.up, Z) < bound, (est.to_dict(), angle_deg(est.up, Z))
    rolled = {"none": 0, "portrait": len(cams), "mixed": len(cams) // 2}[roll]
    assert sum(r in (90, 270) for r in est.rolls_deg) == rolled


def test_the_former_estimate_flips_or_rolls_on_these(garden):
    """The mean image-up axis (the former views.estimate_up) is 90 degrees off for sideways photos."""
    cams = capture("walk", "portrait")
    old = geometry.unit(np.stack([-c.R[1] for c in cams]).mean(0))
    assert angle_deg(old, Z) > 45


def test_common_pitch_is_settled_by_the_ground(garden):
    """Forward-facing cameras all with one orientation, pitched ~25 deg down: the cameras alone
    keep the pitch in up (they cannot tell it), the ground plane in the point cloud removes it."""
    from anigs.cameras import Camera

    pts, _ = garden
    first = capture("forward")
    R = first[0].R
    cams = [Camera(c.K, np.r_[np.c_[R, -R @ c.center], [[0, 0, 0, 1]]], c.width, c.height, c.name) for c in first]
    pitch = np.degrees(np.arcsin(np.median([c.forward @ Z for c in cams])))
    assert pitch < -15
    alone = estimate_up(cams)
    with_points = estimate_up(cams, seen(pts, cams))
    assert angle_deg(alone.up, Z) > 15
    assert angle_deg(with_points.up, Z) < 5, (angle_deg(with_points.up, Z), angle_deg(alone.up, Z))


def test_close_up_without_ground(garden):
    """Only the flowers are reconstructed (no ground, no walls): up comes from the cameras, within
    their common pitch; the ground falls back below all content and nothing raises."""
    pts, lab = garden
    cams = capture("forward")
    flowers = seen(pts[lab == LABEL_IDS["flowers"]], cams)
    est = estimate_up(cams, flowers)
    pitch = abs(np.degrees(np.arcsin(np.median([c.forward @ Z for c in cams]))))
    assert angle_deg(est.up, Z) < pitch + 5
    gr = estimate_ground(flowers, Z, cams)
    assert gr.offset <= flowers[:, 2].min() + 1e-9 or gr.method != "fallback"
    assert gr.camera_height > 0


def test_ground_looking_up_at_a_building(garden, caplog):
    """Only the facade above eye height and a little ground: the densest layer (a ledge or eave
    above the cameras) is not taken for the ground; the plane below the cameras is."""
    pts, lab = garden
    cams = capture("facade")
    facade = pts[(lab == LABEL_IDS["building"]) & (pts[:, 2] > 2.0)]
    ground = pts[(lab == LABEL_IDS["ground"]) & (pts[:, 1] > 2.0)][:60]
    rng = np.random.default_rng(1)   # a window ledge / balcony slab 2.6 m up: the densest layer
    ledge = np.c_[rng.uniform(-4, 4, 400), rng.uniform(4.6, 5.2, 400), np.full(400, 2.6)]
    cloud = np.concatenate([facade, ground, ledge])
    with caplog.at_level(logging.WARNING, logger="anigs.geometry"):
        gr = estimate_ground(cloud, Z, cams)
    assert abs(gr.offset) < 0.05 and gr.method == "below-cameras", gr.to_dict()
    assert gr.camera_height == pytest.approx(1.6, abs=0.15)
    assert any("not below the cameras" in r.getMessage() for r in caplog.records)
    # the former algorithm (densest layer below the median) takes the ledge: cameras below it
    h = cloud[:, 2]
    assert np.median([c.center[2] for c in cams]) < geometry.ground._densest_layer(h, np.percentile(h, 0.5), np.median(h),
                                                                          np.ptp(np.percentile(h, [0.5, 99.5])) / 400)
    # the former masks.vegetation.estimate_ground (now geometry.ground.ground_plane) raised here; it now delegates
    from anigs.geometry.ground import ground_plane as veg_ground

    assert abs(veg_ground(cloud, Z, cams).offset) < 0.05


def test_ground_fallback_logs_and_does_not_raise(caplog):
    """Nothing below the cameras at all: fallback plane under all content, flagged and logged."""
    rng = np.random.default_rng(0)
    cloud = rng.normal(0, 0.3, (500, 3)) + [0, 5, 4.0]     # content entirely above the cameras
    cams = capture("facade", n=6)
    with caplog.at_level(logging.WARNING, logger="anigs.geometry"):
        gr = estimate_ground(cloud, Z, cams)
    assert gr.fallback and gr.method == "fallback"
    assert gr.offset < min(cloud[:, 2].min(), min(c.center[2] for c in cams))
    assert gr.camera_height > 0
    assert any("fallback" in r.getMessage() for r in caplog.records)


def test_up_fallback_logs_and_does_not_crash(caplog):
    """Every photo sideways and no points: roll +90 with up and roll -90 with -up fit equally (a
    sign tie). Documented fallback: the sign for which the cameras look down (they look ~11 deg
    down), flagged and logged. Without cameras: +z."""
    cams = capture("walk", "portrait")
    with caplog.at_level(logging.WARNING, logger="anigs.geometry"):
        est = estimate_up(cams)
    assert est.fallback and est.method == "fallback-look-down"
    assert angle_deg(est.up, Z) < 3
    assert any("undecidable" in r.getMessage() for r in caplog.records)
    empty = estimate_up([])
    assert empty.fallback and np.allclose(empty.up, Z)


def test_estimate_ground_unchanged_where_it_worked(garden):
    """Cameras above the densest low layer: the same plane as the former algorithm (the demo)."""
    pts, _ = garden
    cams = capture("walk")
    gr = estimate_ground(pts, Z, cams)
    assert gr.method == "densest-layer" and not gr.fallback
    assert abs(gr.offset) < 0.03 and gr.camera_height == pytest.approx(1.6, abs=0.1)


def test_scene_extents(garden):
    """The two length scales: the 3DGS camera radius (static fit) and the robust box diagonal (update)."""
    import torch

    pts, _ = garden
    cams = capture("walk")
    centres = np.stack([c.center for c in cams])
    want = 1.1 * np.linalg.norm(centres - centres.mean(0), axis=1).max()
    assert geometry.scene_extent(cams, pts) == pytest.approx(want)
    one = [cams[0]] * 3  # coinciding cameras: the points' radius
    assert geometry.scene_extent(one, pts) == pytest.approx(np.linalg.norm(pts - pts.mean(0), axis=1).max())
    box = torch.tensor([[0.0, 0, 0], [3.0, 4.0, 0.0]]).repeat(50, 1)
    assert geometry.box_diagonal(box) == pytest.approx(5.0, rel=1e-5)
    assert geometry.box_diagonal(torch.zeros(1, 3)) == 1.0
