"""Stage ``render_clip``: render the camera-fixed clip of one view with a round's model.

    anigs render_clip --static static/ [--model round{r-1}/] (--views views/ --view-id ID | --camera-json cam.json) \\
        --out round{r}/ --params '{"num_frames": 25}'

Without ``--model`` (round 0) every frame is the static canonical render. Output: the clip
``round{r}/render/{view}.npz`` (:func:`anigs.video.save_clip`) whose metadata holds the camera,
view id, model path, number of frames and background.
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.typed_config import from_dict
from anigs.stages import contract
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.stages.contract import File
from anigs.stages.update import Outputs as UpdateOutputs

log = logging.getLogger("anigs.render_clip")


@dataclass
class RenderClipConfig:
    """The ``render_clip`` config section."""

    num_frames: int = 25  # frames per clip (the workflow passes animate.frames)
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour (RGB in [0,1])
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend: auto | cpu | torch | gsplat

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "RenderClipConfig":
        cfg = from_dict(RenderClipConfig, d, "render_clip config", KeyError)
        if cfg.num_frames < 1:
            raise ValueError(f"render_clip config: num_frames must be >= 1, got {cfg.num_frames}")
        if len(cfg.background) != 3:
            raise ValueError("render_clip config: background must be 3 numbers")
        return cfg


Config = RenderClipConfig  # the `render_clip` config section


class Outputs(contract.Outputs):
    """A round's folder (``round{r}/``): the rendered clips of its views."""

    STAGE = "render_clip"
    FOLDER = "{scene}/{variant}/round{round}"
    LAYOUT = {"clips": File("render/", "the round's rendered clips"),
              "clip": File("render/{view}.npz", "camera-fixed clip float [T,H,W,3] in [0,1] + metadata "
                                                "(camera, view_id, model, num_frames, background)")}

    def clip(self, view: str) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of ``view``'s rendered clip."""
        from anigs.video import load_clip

        p = self.path("clip", view=view)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the render_clip stage)")
        return load_clip(p)


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    out: Path = field(metadata={"help": "the round's folder (the clip goes to render/{view}.npz)"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the folder of the model that renders "
                                                                        "(omit for round 0: static)"})
    views: ViewsOutputs | None = None
    view_id: str | None = field(default=None, metadata={"help": "id of the view in --views"})
    camera_json: Path | None = field(default=None, metadata={"help": "one camera JSON instead of --views/--view-id"})


def load_scene(canonical_path: str | Path, cfg: RenderClipConfig, model_path: str | Path | None = None):
    """The canonical scene and the model's deformation (None: static) on the config's device
    -> (canonical, deformation | None, background [3])."""
    from anigs.animate.deform import load_model
    from anigs.device import get_device
    from anigs.gaussians import Gaussians

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
    from anigs.animate.frames import render_clip
    from anigs.video import save_clip

    canonical, deformation, bg = scene
    T = cfg.num_frames
    clip = render_clip(canonical, deformation, camera, T, bg, cfg.backend)
    meta = {"camera": camera.to_dict(), "view_id": view_id if view_id is not None else camera.name,
            "num_frames": T, "model": str(model_path) if model_path else None, "canonical": str(canonical_path),
            "background": list(cfg.background), "config": asdict(cfg)}
    save_clip(out, clip.cpu(), meta)
    log.info("rendered %d frames %dx%d of view %s -> %s", T, camera.width, camera.height, meta["view_id"], out)
    return meta


def run(inputs: Inputs, cfg: RenderClipConfig, scene: tuple | None = None) -> Outputs:
    """Render the clip of ``inputs``' camera with its model (none: the static canonical scene);
    ``scene``: the :func:`load_scene` of these inputs, when a caller renders several views."""
    from anigs.cameras import load_camera_json, load_view_camera

    if inputs.camera_json:
        camera = load_camera_json(inputs.camera_json)
    elif inputs.views is not None and inputs.view_id is not None:
        camera = load_view_camera(inputs.views.path("views"), inputs.view_id)
    else:
        raise ValueError("render_clip: give --camera-json FILE, or --views DIR with --view-id ID")
    out = Outputs(inputs.out)
    model = inputs.model.path("model") if inputs.model is not None else None
    canonical = inputs.static.path("canonical")
    scene = scene if scene is not None else load_scene(canonical, cfg, model)
    render_view(scene, camera, out.path("clip", view=inputs.view_id or camera.name), cfg, canonical, model,
                inputs.view_id)
    return out
