"""The ``render_clip`` job: its config section (:class:`RenderClipConfig`), the scene it renders
(:func:`load_scene`: the canonical Gaussians and a round's deformation) and one view's clip
(:func:`render_view`). The stage: :mod:`anigs.stages.render_clip`; the ``round`` stage renders
every view of a round from one :func:`load_scene`."""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar

import torch

from anigs.cameras import Camera
from anigs.typed_config import Section
from anigs.animate.deform import load_model
from anigs.animate.frames import render_clip
from anigs.device import get_device
from anigs.gaussians import Gaussians
from anigs.video import save_clip

log = logging.getLogger("anigs.render_clip")


@dataclass
class RenderClipConfig(Section):
    """The ``render_clip`` config section."""

    num_frames: int = 25  # frames per clip (the workflow passes animate.frames)
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour (RGB in [0,1])
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend: auto | cpu | torch | gsplat

    WHERE: ClassVar[str] = "render_clip config"
    ERROR: ClassVar[type[Exception]] = KeyError

    def validate(self) -> None:
        if self.num_frames < 1:
            raise ValueError(f"render_clip config: num_frames must be >= 1, got {self.num_frames}")
        if len(self.background) != 3:
            raise ValueError("render_clip config: background must be 3 numbers")


def load_scene(canonical_path: str | Path, cfg: RenderClipConfig, model_path: str | Path | None = None):
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
    """Render ``camera``'s clip of a :func:`load_scene` scene to ``out``; returns the clip's metadata
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
