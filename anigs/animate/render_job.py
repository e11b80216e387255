"""The ``render_clip`` job (its config section: :class:`anigs.animate.config.RenderClipConfig`): the
scene it renders (:func:`load_animated_scene`: the canonical Gaussians and a round's deformation) and one view's clip
(:func:`render_view`). The stage: :mod:`anigs.stages.render_clip`; the ``round`` stage renders
every view of a round from one :func:`load_animated_scene`."""
from __future__ import annotations

import logging
from dataclasses import asdict
from pathlib import Path

import torch

from anigs.cameras import Camera
from anigs.animate.config import RenderClipConfig
from anigs.animate.deform import load_model
from anigs.animate.frames import render_clip
from anigs.device import get_device
from anigs.gaussians import Gaussians
from anigs.video import save_clip

log = logging.getLogger("anigs.render_clip")


def load_animated_scene(canonical_path: str | Path, cfg: RenderClipConfig, model_path: str | Path | None = None):
    """The canonical scene and the model's deformation (None: static) on the config's device
    -> (canonical, deformation | None, background [3])."""

    canonical = Gaussians.load_ply(canonical_path)
    deformation = None
    if model_path:
        canonical, deformation, _ = load_model(model_path, canonical)
        if deformation.num_frames != cfg.num_frames:
            raise ValueError(f"render_clip: model {model_path} has T={deformation.num_frames} frames but "
                             f"render_clip.num_frames={cfg.num_frames}; use the same frame count in every round")
    dev = get_device(cfg.device)
    canonical = canonical.to(dev)
    if deformation is not None:
        deformation = deformation.to(dev)
    return canonical, deformation, torch.tensor(cfg.background, dtype=torch.float32, device=dev)


def render_view(scene: tuple, camera: Camera, out: str | Path, cfg: RenderClipConfig, canonical_path: str | Path,
                model_path: str | Path | None = None, view_id: str | None = None) -> dict:
    """Render ``camera``'s clip of a :func:`load_animated_scene` scene to ``out``; returns the clip's metadata
    (the paths are recorded as given)."""

    canonical, deformation, bg = scene
    T = cfg.num_frames
    clip = render_clip(canonical, deformation, camera, T, bg, cfg.backend)
    meta = {"camera": camera.to_dict(), "view_id": view_id if view_id is not None else camera.name,
            "num_frames": T, "model": str(model_path) if model_path else None, "canonical": str(canonical_path),
            "background": list(cfg.background), "config": asdict(cfg)}
    save_clip(out, clip.cpu(), meta)
    log.info("rendered %d frames %dx%d of view %s -> %s", T, camera.width, camera.height, meta["view_id"], out)
    return meta
