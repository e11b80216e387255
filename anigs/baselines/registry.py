"""The baselines by name: ``get_baseline``, ``fit_baseline`` and ``run_baseline`` (the path-level
entry point of the update stage's baseline variants)."""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import torch

from anigs.animate.deform import save_model
from anigs.animate.update import ViewData
from anigs.baselines import lifting, physics
from anigs.baselines.base import BASELINES, MODEL_KIND, BaselineResult
from anigs.cameras import Camera, load_view_camera
from anigs.gaussians import Gaussians
from anigs.io import write_json
from anigs.video import load_clip

log = logging.getLogger("anigs.baselines")

FitFn = Callable[[Gaussians, torch.Tensor, list[ViewData], Mapping[str, Any] | None], BaselineResult]
FITS: dict[str, FitFn] = {"lifting": lifting.fit, "physics": physics.fit}


def get_baseline(name: str) -> FitFn:
    """The ``fit`` function of baseline ``name`` (``lifting`` | ``physics``)."""
    if name not in FITS:
        raise ValueError(f"unknown baseline {name!r}; available: {list(BASELINES)}")
    return FITS[name]


def fit_baseline(name: str, canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData],
                 config: Mapping[str, Any] | None = None) -> BaselineResult:
    """Fit baseline ``name`` (see module docstring); the same inputs as ``run_update``."""
    return get_baseline(name)(canonical, dynamic_mask, views, config)


def load_views(targets: list[str | Path], view_json: str | Path | None = None,
               view_ids: list[str] | None = None) -> list[ViewData]:
    """Target clips (.npz) and their cameras: from ``view_json`` by view id (default: the file
    stems), else from each clip's metadata (``camera``)."""
    if view_ids is not None and len(view_ids) != len(targets):
        raise ValueError(f"{len(view_ids)} view ids for {len(targets)} targets")
    views = []
    for k, t in enumerate(targets):
        clip, meta = load_clip(t)
        if view_json is not None:
            cam = load_view_camera(view_json, view_ids[k] if view_ids else Path(t).stem)
        elif "camera" in meta:
            cam = Camera.from_dict(meta["camera"])
        else:
            raise KeyError(f"target {t} has no camera in its metadata; pass view_json")
        views.append(ViewData(cam, torch.from_numpy(clip)))
    return views


def run_baseline(method: str, canonical: str | Path | Gaussians, dynamic: str | Path | np.ndarray | torch.Tensor,
                 targets: list[str | Path], out: str | Path, params: Mapping[str, Any] | None = None,
                 view_json: str | Path | None = None, view_ids: list[str] | None = None,
                 log_json: str | Path | None = None) -> BaselineResult:
    """Path-level entry point for a CLI stage: fit ``method`` and write ``out`` (a ``model.pt``
    readable by :func:`anigs.animate.deform.load_model`).

    Args:
        method: ``lifting`` | ``physics``.
        canonical: canonical 3DGS PLY (or Gaussians).
        dynamic: an ``.npy`` [N] (bool, or int effect labels: the masks stage's sets) or the array itself.
        targets: refined target clips (.npz), one per view (lifting uses all, physics one).
        out: output ``model.pt``.
        params: the baseline's config section (unknown keys rejected).
        view_json / view_ids: cameras (default: from each clip's metadata).
        log_json: optional JSON with timing and the fit's facts.
    """
    t0 = time.perf_counter()
    canon = canonical if isinstance(canonical, Gaussians) else Gaussians.load_ply(canonical)
    if isinstance(dynamic, (str, Path)):
        if not Path(dynamic).exists():
            raise FileNotFoundError(f"dynamic selection not found: {dynamic}")
        dynamic = np.load(dynamic)
    mask = torch.as_tensor(np.asarray(dynamic))
    if mask.ndim != 1 or mask.shape[0] != canon.num:
        raise ValueError(f"dynamic selection has shape {tuple(mask.shape)}, expected [{canon.num}]")
    views = load_views(list(targets), view_json, view_ids)
    result = fit_baseline(method, canon, mask, views, params)
    cfg = dict(params or {})
    save_model(out, result.deformation, result.canonical, {"method": method, **cfg},
               extra={"kind": MODEL_KIND, "method": method, "targets": [str(t) for t in targets],
                      "info": _jsonable(result.info)})
    total = time.perf_counter() - t0
    if log_json is not None:
        write_json(log_json, {"method": method, "seconds": total, "fit_seconds": result.seconds,
                              "info": _jsonable(result.info), "config": cfg})
    log.info("%s baseline: wrote %s (%d dynamic Gaussians, K=%d, T=%d) in %.1f s", method, out,
             result.deformation.num_dynamic, result.deformation.num_bases, result.deformation.num_frames, total)
    return result


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.generic,)):
        return obj.item()
    if isinstance(obj, (np.ndarray, torch.Tensor)):
        return np.asarray(obj).tolist()
    return obj
