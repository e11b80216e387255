"""The training data of one model update: target clips with their cameras, static references and
the dynamic set (:class:`anigs.animate.update.ViewData` inputs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from anigs.cameras import Camera, load_camera_json, load_view_camera
from anigs.animate.target_frames import ClipFrames
from anigs.animate.update import ViewData, static_references
from anigs.images import load_image


def load_reference(path: str | Path) -> torch.Tensor:
    """A static reference image (for L_cano) -> float32 [H,W,3]: a .png, a .npy [H,W,3] or a
    clip .npz (its frame 0)."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"static reference not found: {p}")
    if p.suffix == ".npz":
        img = ClipFrames(p)[0].numpy()
    elif p.suffix == ".npy":
        img = np.load(p).astype(np.float32)
    else:
        img = load_image(p)
    if img.ndim != 3 or img.shape[-1] != 3 or not np.isfinite(img).all():
        raise ValueError(f"static reference {p}: expected a finite [H,W,3] image, got shape {img.shape}")
    return torch.from_numpy(np.ascontiguousarray(img))


def target_cameras(targets: list[str], metas: list[dict], views_json: str | Path | None, view_ids: list[str] | None,
                   camera_json: list[str] | None) -> list[Camera]:
    """One camera per target clip: from ``camera_json`` (one file each), else from ``views_json`` with
    ``view_ids`` (default: the targets' file stems), else from each clip's metadata (``camera``)."""
    n = len(targets)
    if camera_json:
        if len(camera_json) != n:
            raise ValueError(f"update: {len(camera_json)} --camera-json files for {n} targets")
        return [load_camera_json(p) for p in camera_json]
    if views_json:
        ids = view_ids or [Path(t).stem for t in targets]
        if len(ids) != n:
            raise ValueError(f"update: {len(ids)} --view-ids for {n} targets")
        return [load_view_camera(views_json, i) for i in ids]
    cams = []
    for t, m in zip(targets, metas):
        if "camera" not in m:
            raise KeyError(f"update: target {t} has no camera in its metadata; pass --camera-json or --views")
        cams.append(Camera.from_dict(m["camera"]))
    return cams


def training_views(canonical, targets: list[str], views_json: str | Path | None, view_ids: list[str] | None,
                   camera_json: list[str] | None, static_refs: list[str] | None, cfg) -> list:
    """One :class:`anigs.animate.update.ViewData` per target clip: its frames (a
    :class:`anigs.animate.target_frames.ClipFrames`, read from disk as the steps sample them: no clip
    is held in memory), its camera (:func:`target_cameras`) and its static reference for L_cano
    (``static_refs``, else renders of the ``canonical`` Gaussians when ``cfg.lambda_cano > 0``, else
    none). ``cfg``: the update config."""

    clips = [ClipFrames(t) for t in targets]
    cams = target_cameras(targets, [c.meta for c in clips], views_json, view_ids, camera_json)
    refs: list[torch.Tensor | None] = [None] * len(clips)
    if static_refs:
        if len(static_refs) != len(clips):
            raise ValueError(f"update: {len(static_refs)} --static-refs for {len(clips)} targets")
        refs = [load_reference(p) for p in static_refs]
    elif cfg.lambda_cano > 0:
        refs = static_references(canonical, cams, torch.tensor(cfg.background, dtype=torch.float32), cfg.backend)
    return [ViewData(c, clip, r) for c, clip, r in zip(cams, clips, refs)]


def dynamic_set(dynamic: np.ndarray, num_gaussians: int, where: str, labels: np.ndarray | None = None,
                labels_where: str = "") -> torch.Tensor:
    """The dynamic selection of an update: bool [N] (or int effect labels [N], 0 = static). With
    ``labels`` (int [N], the masks stage's effect labels) these, checked to label exactly the dynamic
    Gaussians. ``where``/``labels_where`` name the files in errors."""
    out = torch.from_numpy(dynamic)
    if out.ndim != 1 or out.shape[0] != num_gaussians:
        raise ValueError(f"{where}: shape {tuple(out.shape)}, expected [{num_gaussians}] (one per Gaussian "
                         f"of the canonical scene)")
    if labels is not None:
        lab = torch.from_numpy(labels.astype(np.int64))
        if lab.shape != out.shape or not torch.equal(lab != 0, out != 0):
            raise ValueError(f"update: {labels_where} (effect labels, shape {tuple(lab.shape)}) does not "
                             f"label exactly the dynamic Gaussians of {where}: re-run the masks stage")
        out = lab
    return out
