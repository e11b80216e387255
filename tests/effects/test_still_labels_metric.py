"""gt/moving_labelled_still (anigs/metrics/still_labels.py): the share of the model's moving
Gaussians whose ground-truth label must stay still, on a hand-built model."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.animate import deform
from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians
from anigs.metrics.still_labels import KEY, moving_labelled_still
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.synth import ALL_LABELS, LABEL_IDS
from tests._gt import write_gt


@pytest.mark.parametrize("wrong", [0, 15])
def test_share_of_moving_gaussians_labelled_still(tmp_path, wrong):
    rng = np.random.default_rng(0)
    n_leaf, n_ground = 100, 80
    means = np.concatenate([rng.uniform(-1, 1, (n_leaf, 3)) + [0, 0, 2], rng.uniform(-1, 1, (n_ground, 3)) * [1, 1, 0]])
    labels = np.array([LABEL_IDS["foliage"]] * n_leaf + [LABEL_IDS["ground"]] * n_ground)
    g = Gaussians.from_points(torch.tensor(means, dtype=torch.float32), torch.full((len(means), 3), 0.5))
    cams = [Camera(intrinsics_from_fov(60, 32, 24), look_at((5 * np.cos(a), 5 * np.sin(a), 2), (0, 0, 0)), 32, 24,
                   f"c{i}") for i, a in enumerate(np.linspace(0, 2 * np.pi, 6, endpoint=False))]
    gt = CaptureOutputs.from_gt(write_gt(tmp_path, g, labels, {"labels": {str(k): v for k, v in ALL_LABELS.items()}}, cams))
    ply = tmp_path / "canonical.ply"
    g.save_ply(ply)
    dyn = torch.tensor(list(range(n_leaf)) + list(range(n_leaf, n_leaf + wrong)))  # every leaf, `wrong` ground
    T, K = 9, 4
    d = deform.DCTDeformation(dyn, T, K, rotation=False, num_gaussians=g.num)
    with torch.no_grad():
        d.pos_coeffs.copy_(torch.from_numpy(rng.normal(0, 0.05, (len(dyn), 3, K))).float())
    deform.save_model(tmp_path / "model.pt", d, g)
    rec = moving_labelled_still(tmp_path / "model.pt", ply, gt, tmp_path / "cameras.json")[KEY]
    assert rec["available"] and rec["higher_is_better"] is False
    assert rec["samples"]["moving_gaussians"] == n_leaf + wrong
    assert rec["value"] == pytest.approx(wrong / (n_leaf + wrong))
    assert moving_labelled_still(None, None, None, None) == {}  # photo scenes: no figure
