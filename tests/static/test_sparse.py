"""Weight-free help for sparse captures (``static.sparse``): points from photo pairs, DropGaussian."""
from __future__ import annotations

import numpy as np
import pytest
import torch

cv2 = pytest.importorskip("cv2")

from anigs.cameras import Camera, intrinsics_from_fov, look_at  # noqa: E402
from anigs.static.fit import StaticConfig, fit_static  # noqa: E402
from anigs.static.sparse import dropout  # noqa: E402
from anigs.static.pair_points import _fundamental, guided_matches, _features, neighbour_pairs, pair_points  # noqa: E402

from tests.static.test_fit import FAST, make_scene, sfm_points  # noqa: E402

pytestmark = pytest.mark.usefixtures("one_thread")

HALF = 2.0  # the textured ground covers [-HALF, HALF]^2 at z = 0


def _ground_photos(n: int = 6, width: int = 320, height: int = 240, seed: int = 0):
    """A textured ground plane (z = 0) photographed from ``n`` cameras along a walk: the photos are exact
    projections (a homography per camera), uint8 [H,W,3]."""
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.integers(0, 256, (1024, 1024, 3)).astype(np.uint8), (0, 0), 2.0)
    s = 2 * HALF / tex.shape[0]  # world units per texture pixel
    A = np.array([[s, 0, -HALF + 0.5 * s], [0, s, -HALF + 0.5 * s], [0, 0, 1.0]])  # texture pixel -> (x, y, 1)
    K = intrinsics_from_fov(60, width, height)
    shift = np.array([[1, 0, -0.5], [0, 1, -0.5], [0, 0, 1.0]])  # continuous (centre +0.5) -> cv2 pixel
    cams, photos = [], []
    for i in range(n):
        x = -0.8 + 1.6 * i / (n - 1)
        cam = Camera(K, look_at((x, -2.5, 2.0), (0.6 * x, 0.0, 0.0)), width, height, f"{i:02d}.png")
        H = shift @ K @ cam.viewmat[:3][:, [0, 1, 3]] @ A
        photos.append(cv2.warpPerspective(tex, H, (width, height), flags=cv2.INTER_LINEAR))
        cams.append(cam)
    return photos, cams


def test_pair_points_lie_on_the_photographed_surface():
    photos, cams = _ground_photos()
    pp = pair_points(photos, cams, per_photo=2)
    assert pp.pairs == len(neighbour_pairs(cams, 2)) and pp.points > 500, pp.as_dict()
    z = np.abs(pp.xyz[:, 2])
    assert np.quantile(z, 0.95) < 0.02 * HALF, np.quantile(z, [0.5, 0.95, 1.0])  # on the ground (4 units wide)
    assert (np.abs(pp.xyz[:, :2]) <= HALF + 0.05).all(1).mean() > 0.99  # two-view points: a few mismatches
    assert pp.rgb.shape == pp.xyz.shape and 0 <= pp.rgb.min() and pp.rgb.max() <= 1


def test_pair_points_drop_what_lies_far_outside_the_sfm_points():
    photos, cams = _ground_photos()
    full = pair_points(photos, cams, per_photo=2)
    box = np.array([[-0.2, -0.2, 0.0], [0.2, 0.2, 0.0]])  # a small, flat SfM cloud: widened by 0.2 all round
    kept = pair_points(photos, cams, per_photo=2, within=box)
    assert 0 < kept.points < full.points
    assert (np.abs(kept.xyz) <= 0.4 + 1e-9).all() and np.abs(kept.xyz[:, 2]).max() > 0  # off-plane kept


def test_guided_matches_keep_the_epipolar_geometry():
    photos, cams = _ground_photos()
    (ka, da), (kb, db) = _features(photos[0], 4000), _features(photos[1], 4000)
    F = _fundamental(cams[0], cams[1])
    m = guided_matches(ka, da, kb, db, F, 0.8, 1.5)
    assert len(m) > 200
    assert len(set(m[:, 0])) == len(m) and len(set(m[:, 1])) == len(m)  # one-to-one
    ha, hb = np.c_[ka[m[:, 0]], np.ones(len(m))], np.c_[kb[m[:, 1]], np.ones(len(m))]
    lines = ha @ F.T
    assert (np.abs((hb * lines).sum(1)) / np.hypot(lines[:, 0], lines[:, 1]) <= 1.5 + 1e-9).all()
    # a wrong geometry (the second camera's pose from a photo farther along) finds far fewer
    wrong = guided_matches(ka, da, kb, db, _fundamental(cams[0], cams[4]), 0.8, 1.5)
    assert len(wrong) < 0.2 * len(m)


def test_dropout_leaves_out_a_share_and_compensates_the_rest():
    assert dropout(1000, 0.0, torch.Generator().manual_seed(0), torch.device("cpu")) is None
    f = dropout(20000, 0.2, torch.Generator().manual_seed(0), torch.device("cpu"))
    assert set(f.unique().tolist()) == {0.0, 1.25}
    assert abs(float((f == 0).float().mean()) - 0.2) < 0.01
    assert torch.equal(f, dropout(20000, 0.2, torch.Generator().manual_seed(0), torch.device("cpu")))


def test_config_rejects_bad_sparse_values():
    with pytest.raises(ValueError, match="static.sparse.drop_rate"):
        StaticConfig.from_dict({"sparse": {"drop_rate": 1.0}})
    with pytest.raises(ValueError, match="static.sparse config: unknown keys"):
        StaticConfig.from_dict({"sparse": {"dropgaussian": 0.2}})


@pytest.fixture(scope="module")
def scene():
    return make_scene()


def test_dropout_fit_is_deterministic_and_evaluates_every_gaussian(scene):
    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    plain = fit_static(imgs, cams, p, c, StaticConfig.from_dict(FAST), progress=False)[1]
    cfg = StaticConfig.from_dict({**FAST, "sparse": {"drop_rate": 0.5}})
    (g1, m1), (g2, m2) = (fit_static(imgs, cams, p, c, cfg, progress=False) for _ in range(2))
    for k, v in g1.params().items():
        assert torch.equal(v, g2.params()[k]), k
    assert m1["curve"][0]["test_psnr"] == plain["curve"][0]["test_psnr"]  # the start, evaluated whole
    assert m1["test_psnr"] != plain["test_psnr"]  # the steps saw fewer Gaussians


def test_pair_points_read_only_the_training_photos(scene, monkeypatch):
    import anigs.static.sparse as sparse

    gt, cams, imgs = scene
    p, c = sfm_points(gt, every=4)
    seen = []

    real = sparse.pair_points

    def spy(*args, **kwargs):
        seen.append([cam.name for cam in args[1]])
        return real(*args, **kwargs)

    monkeypatch.setattr(sparse, "pair_points", spy)
    cfg = StaticConfig.from_dict({**FAST, "background": "random", "sparse": {"pair_points": True, "pair_neighbours": 2}})
    _, m = fit_static(imgs, cams, p, c, cfg, progress=False)
    held = set(m["holdout"])
    assert seen and held and not held & set(seen[0]) and len(seen[0]) == len(cams) - len(held)
    assert m["pair_points"]["pairs"] > 0 and m["init_gaussians"] >= len(p) + m["pair_points"]["points"] - 1


def _plane_depth(cam: Camera) -> torch.Tensor:
    """The camera-space depth [H,W] of the ground plane z = 0 at each pixel centre."""
    from anigs.static.warp import _rays

    rays = _rays(cam, torch.device("cpu")).double().numpy()  # camera space, z = 1
    R, C = cam.R, cam.center
    d_world = rays @ R  # R^T r per row
    t = -C[2] / d_world[:, 2]  # along the ray to z = 0: the camera-space z is t (rays have z = 1)
    return torch.from_numpy(t.reshape(cam.height, cam.width)).float()


def test_warp_loss_is_lowest_at_the_true_depth_and_reaches_the_depth():
    from anigs.static.warp import WarpLoss, nearest_views

    photos, cams = _ground_photos(n=5)
    assert nearest_views(cams, 2)[0] == [1, 2] and nearest_views(cams, 2)[2] == [1, 3]
    imgs = [torch.from_numpy(p) for p in photos]
    warp = WarpLoss(cams, 2, torch.device("cpu"))
    alpha = torch.ones(cams[2].height, cams[2].width)
    target = imgs[2].float() / 255.0
    true = _plane_depth(cams[2])
    losses = {f: float(warp(2, true * f, alpha, target, imgs)) for f in (0.8, 0.95, 1.0, 1.05, 1.25)}
    assert losses[1.0] < 0.02 and min(losses, key=losses.get) == 1.0, losses
    assert losses[0.8] > 3 * losses[1.0] and losses[1.25] > 3 * losses[1.0], losses
    depth = (true * 1.05).requires_grad_()
    warp(2, depth, alpha, target, imgs).backward()
    assert depth.grad is not None and float(depth.grad.abs().sum()) > 0
    assert float(warp(2, true, torch.zeros_like(alpha), target, imgs)) == 0.0  # nothing opaque: no loss
