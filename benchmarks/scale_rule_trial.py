"""A trial rule on the labelled real-capture benchmark: plant Gaussians much larger than their region's
median stay still (tried for anigs 0.10 and not kept; README, "What moves on real captures").

    K=3 MODE=region [V=1] python benchmarks/scale_rule_trial.py --captures ../shared/captures --cache DIR \\
        --no-fit --capture flower-llff lund-street --kind user

Wraps :func:`anigs.effects.detect.apply_rules`: after the geometry rules, a foliage / grass / flower
Gaussian whose largest scale exceeds ``K`` x the median of its region's (``MODE=region``) or of all plant
Gaussians (``MODE=all``), and whose own colour's brightest channel is under ``V`` (1: any), leaves its
region; then runs ``benchmarks/real_captures.py`` with the remaining arguments. Use a ``--cache`` of its
own: the phrasing folders are keyed by the effects code, which this wrapper does not change.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from anigs.effects import detect  # noqa: E402
from anigs.effects.config import REGIONS  # noqa: E402

K = float(os.environ.get("K", "3"))
MODE = os.environ.get("MODE", "region")
V = float(os.environ.get("V", "1"))
PLANTS = [REGIONS.index(r) for r in ("foliage", "grass", "flowers")]
_rules = detect.apply_rules


def _with_scale_rule(g, cues, region_of, *args, **kwargs):
    ruled = _rules(g, cues, region_of, *args, **kwargs)
    new = ruled.region_of
    plant = np.isin(new, PLANTS)
    if plant.any():
        scale = g.scales.max(1).values.double().numpy()
        colour = (0.5 + 0.28209479 * g.sh[:, 0, :]).clamp(0, 1).double().numpy()
        if MODE == "all":
            big = plant & (scale > K * np.median(scale[plant]))
        else:
            big = np.zeros_like(plant)
            for k in np.unique(new[plant]):
                m = new == k
                big |= m & (scale > K * np.median(scale[m]))
        if V < 1:
            big &= colour.max(1) < V
        print(f"# scale rule K={K:g} {MODE} V={V:g}: {int(big.sum())} of {int(plant.sum())} plant Gaussians still",
              flush=True)
        ruled.region_of = np.where(big, -1, new)
    return ruled


if __name__ == "__main__":
    detect.apply_rules = _with_scale_rule
    import real_captures

    sys.argv = ["real_captures.py", *sys.argv[1:]]
    real_captures.main()
