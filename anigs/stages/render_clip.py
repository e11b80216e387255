"""Stage ``render_clip``: render the camera-fixed clip of one view with a round's model.

    anigs render_clip --canonical static/canonical.ply [--model round{r-1}/model.pt] \\
        (--view-json views/views.json --view-id ID | --camera-json cam.json) \\
        --out round{r}/render/ID.npz --params '{"num_frames": 25}'

Without ``--model`` (round 0) every frame is the static canonical render. Output: a clip
npz (:func:`anigs.video.save_clip`) whose metadata holds the camera, view id, model path,
number of frames and background.
"""
from __future__ import annotations

import argparse
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch

from anigs.cameras import Camera
from anigs.typed_config import from_dict

log = logging.getLogger("anigs.render_clip")


@dataclass
class RenderClipConfig:
    """The ``render_clip`` config section."""

    num_frames: int = 25
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    device: str = "auto"
    backend: str = "auto"

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "RenderClipConfig":
        cfg = from_dict(RenderClipConfig, d, "render_clip config", KeyError)
        if cfg.num_frames < 1:
            raise ValueError(f"render_clip config: num_frames must be >= 1, got {cfg.num_frames}")
        if len(cfg.background) != 3:
            raise ValueError("render_clip config: background must be 3 numbers")
        return cfg


Config = RenderClipConfig  # the `render_clip` config section


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


def run(canonical_path: str | Path, camera: Camera, out: str | Path, cfg: RenderClipConfig,
        model_path: str | Path | None = None, view_id: str | None = None) -> dict:
    """Render ``camera``'s clip with the model at ``model_path`` (none: the static canonical scene)
    and save it to ``out``; returns the clip's metadata."""
    scene = load_scene(canonical_path, cfg, model_path)
    return render_view(scene, camera, out, cfg, canonical_path, model_path, view_id)


# ---- command line: anigs render_clip ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p)
    p.add_argument("--model", default=None, help="model.pt of the previous round (omit for round 0: static)")
    p.add_argument("--view-json", default=None, help="views JSON (with --view-id)")
    p.add_argument("--view-id", default=None, help="id of the view in --view-json")
    p.add_argument("--camera-json", default=None, help="a single camera JSON instead of --view-json/--view-id")
    add_out(p, "output clip .npz")
    add_params(p, "render_clip")


def main(args: argparse.Namespace) -> int:
    from anigs.cameras import load_camera_json, load_view_camera
    from anigs.cli import parse_params

    cfg = RenderClipConfig.from_dict(parse_params(args.params))
    if args.camera_json:
        camera = load_camera_json(args.camera_json)
    elif args.view_json and args.view_id is not None:
        camera = load_view_camera(args.view_json, args.view_id)
    else:
        raise ValueError("render_clip: give --camera-json FILE, or --view-json FILE with --view-id ID")
    run(args.canonical, camera, args.out, cfg, model_path=args.model, view_id=args.view_id)
    return 0
