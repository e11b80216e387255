"""``anigs render-clip``: render the camera-fixed clip of one view with a round's model.

    anigs render-clip --canonical static/canonical.ply [--model round{r-1}/model.pt] \\
        (--view-json views/views.json --view-id ID | --camera-json cam.json) \\
        --out round{r}/render/ID.npz --params '{"num_frames": 25}'

Without ``--model`` (round 0) every frame is the static canonical render. Output: a clip
npz (:func:`anigs.video.save_clip`) whose metadata holds the camera, view id, model path,
number of frames and background.
"""
from __future__ import annotations

import argparse
import json
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch

from anigs.cameras import Camera
from anigs.configs import reject_unknown_keys

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
        d = dict(d or {})
        reject_unknown_keys(RenderClipConfig, d, "render_clip config", KeyError)
        cfg = RenderClipConfig(**d)
        if cfg.num_frames < 1:
            raise ValueError(f"render_clip config: num_frames must be >= 1, got {cfg.num_frames}")
        if len(cfg.background) != 3:
            raise ValueError("render_clip config: background must be 3 numbers")
        return cfg


def _is_camera_dict(d: Any) -> bool:
    return isinstance(d, dict) and "K" in d and "viewmat" in d


def load_view_camera(path: str | Path, view_id: str) -> Camera:
    """The camera of view ``view_id`` in a views JSON.

    Accepted layouts: a list of entries, or a dict with the list under ``views`` (or
    ``cameras``); an entry is ``{"id": ..., "camera": {Camera dict}}`` or a Camera dict whose
    ``id``/``name`` is the view id.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"views file not found: {path}")
    data = json.loads(path.read_text())
    entries = data
    if isinstance(data, dict):
        entries = next((data[k] for k in ("views", "cameras") if k in data), None)
        if entries is None:
            raise KeyError(f"{path}: expected a list of views or a dict with 'views' or 'cameras'")
    ids = []
    for e in entries:
        eid = str(e.get("id", e.get("name", "")))
        ids.append(eid)
        if eid == str(view_id):
            cam = e.get("camera", e)
            if not _is_camera_dict(cam):
                raise KeyError(f"{path}: view {view_id!r} has no camera dict (K, viewmat, width, height)")
            cam = dict(cam)
            cam.setdefault("name", eid)
            return Camera.from_dict(cam)
    raise KeyError(f"{path}: no view with id {view_id!r}; views present: {ids}")


def load_camera_json(path: str | Path) -> Camera:
    """A single camera JSON (``Camera.to_dict()``; also accepts ``{"camera": {...}}``)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"camera file not found: {path}")
    d = json.loads(path.read_text())
    if isinstance(d, dict) and "camera" in d and _is_camera_dict(d["camera"]):
        d = d["camera"]
    if not _is_camera_dict(d):
        raise KeyError(f"{path}: not a camera dict (needs K, viewmat, width, height)")
    return Camera.from_dict(d)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--canonical", required=True, help="canonical 3DGS PLY (static/canonical.ply)")
    p.add_argument("--model", default=None, help="model.pt of the previous round (omit for round 0: static)")
    p.add_argument("--view-json", default=None, help="views JSON (with --view-id)")
    p.add_argument("--view-id", default=None, help="id of the view in --view-json")
    p.add_argument("--camera-json", default=None, help="a single camera JSON instead of --view-json/--view-id")
    p.add_argument("--out", required=True, help="output clip .npz")
    p.add_argument("--params", default=None, help="render_clip config section as JSON (or @file)")


def run(args: argparse.Namespace) -> int:
    from anigs.animated import render_clip
    from anigs.cli import parse_params
    from anigs.deform import load_model
    from anigs.device import get_device
    from anigs.gaussians import Gaussians
    from anigs.video import save_clip

    cfg = RenderClipConfig.from_dict(parse_params(args.params))
    if args.camera_json:
        camera = load_camera_json(args.camera_json)
    elif args.view_json and args.view_id is not None:
        camera = load_view_camera(args.view_json, args.view_id)
    else:
        raise ValueError("render-clip: give --camera-json FILE, or --view-json FILE with --view-id ID")
    canonical = Gaussians.load_ply(args.canonical)
    deformation = None
    T = cfg.num_frames
    if args.model:
        canonical, deformation, _ = load_model(args.model, canonical)
        if deformation.num_frames != T:
            raise ValueError(f"render-clip: model {args.model} has T={deformation.num_frames} frames but "
                             f"render_clip.num_frames={T}; use the same frame count in every round")
    dev = get_device(cfg.device)
    canonical = canonical.to(dev)
    if deformation is not None:
        deformation = deformation.to(dev)
    bg = torch.tensor(cfg.background, dtype=torch.float32, device=dev)
    clip = render_clip(canonical, deformation, camera, T, bg, cfg.backend)
    meta = {"camera": camera.to_dict(), "view_id": args.view_id if args.view_id is not None else camera.name,
            "num_frames": T, "model": str(args.model) if args.model else None, "canonical": str(args.canonical),
            "background": list(cfg.background), "config": asdict(cfg)}
    save_clip(args.out, clip.cpu(), meta)
    log.info("rendered %d frames %dx%d of view %s -> %s", T, camera.width, camera.height, meta["view_id"], args.out)
    return 0
