"""The paper's comparison methods, behind one interface (:mod:`anigs.baselines.base`).

- ``lifting`` (:mod:`anigs.baselines.lifting`): Gaussians2Life-style, per-view 2D motion lifted
  to per-Gaussian 3D trajectories through the rendered depth.
- ``physics`` (:mod:`anigs.baselines.physics`): PhysDreamer-style, a mass-spring material
  response to wind fitted to one view's refined clip.

Both take the model update's inputs and return a DCT deformation model (``model.pt``), so
final renders, export and evaluation treat them exactly like ours.
"""
from anigs.baselines.base import BASELINES, BaselineResult
from anigs.baselines.registry import fit_baseline, get_baseline, run_baseline

__all__ = ["BASELINES", "BaselineResult", "fit_baseline", "get_baseline", "run_baseline"]
