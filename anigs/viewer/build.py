"""``build_viewer``: a self-contained viewer folder for an animated scene.

The folder is the view stage's (``out``: its ``Outputs``, :mod:`anigs.stages.view`, names the
files; open its page directly, or serve it with ``anigs view --serve``), by key:

    index          the WebGL2 viewer's page (package data anigs/viewer/static/viewer.html, no CDN),
                   its viewer.css and *.js beside it
    config         window.ANIGS_CONFIG: queued views, up, background, fps, the scene's file names
    scene          the compact animated scene (anigs.viewer.compact)
    embed          the same bytes base64-encoded (``embed``): pages opened from file:// cannot
                   fetch(), they load this script instead

The page loads the config script by its name (``<script src=...>`` in viewer.html); the scene and
its embedded copy are named in the config.
"""
from __future__ import annotations

import base64
import json
import logging
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from anigs.animate.deform import DCTDeformation, load_model, load_model_payload
from anigs.gaussians import Gaussians
from anigs.io import StageFolder, atomic_path, atomic_write_bytes, atomic_write_text, read_json
from anigs.viewer.compact import decode_compact, encode_compact
from anigs.views import cameras_from_views

log = logging.getLogger("anigs.viewer")

DEFAULT_BACKGROUND = (0.5, 0.5, 0.5)  # the final renders' default background (final.background)
PAGE = "viewer.html"  # package data: written as the layout's page (``index``)
STATIC_FILES = ("viewer.css", "format.js", "sort-worker.js", "shaders.js", "renderer.js", "camera.js", "viewer.js",
                "ui.js")


def load_animated(model_path: str | Path, canonical: str | Path | Gaussians | None = None
                  ) -> tuple[Gaussians, DCTDeformation, dict[str, Any]]:
    """(trained canonical Gaussians, deformation, model config) from ``model.pt`` or a compact file.

    ``model.pt`` needs the canonical PLY unless it stores every canonical attribute.
    """
    path = Path(model_path)
    if path.suffix == ".anigs":
        scene = decode_compact(path.read_bytes(), str(path))
        return scene.canonical, scene.deformation, dict(scene.header.get("extra", {}).get("config", {}))
    if canonical is None:
        payload = load_model_payload(path)
        stored = payload.get("canonical")
        if stored is None:
            raise ValueError(f"{path} holds only the canonical positions: pass the canonical PLY (--canonical)")
        stored = dict(stored, means=payload["canonical_means"])
        canonical = Gaussians(**{k: stored[k] for k in ("means", "quats", "log_scales", "opacity_logits", "sh")})
    g, deformation, payload = load_model(path, canonical)
    return g, deformation, dict(payload.get("config") or {})


def views_config(views_json: str | Path | dict | None) -> dict[str, Any]:
    """The viewer's ``views`` (id + OpenCV camera dicts), ``up`` and ``roi_centroid`` from views.json."""
    if views_json is None:
        return {"views": [], "up": [0.0, 0.0, 1.0], "roi_centroid": None}
    data = views_json if isinstance(views_json, dict) else read_json(views_json)
    cams = cameras_from_views(data)
    return {"views": [{"id": c.name, "camera": c.to_dict()} for c in cams],
            "up": [float(x) for x in data.get("up", [0.0, 0.0, 1.0])],
            "roi_centroid": data.get("roi_centroid")}


def copy_static(out: StageFolder) -> list[str]:
    """Copy the viewer's HTML/JS/CSS from the package data into ``out`` (the page as its ``index``);
    returns the names written."""
    pkg = resources.files("anigs.viewer") / "static"
    atomic_write_bytes(out.path("index"), (pkg / PAGE).read_bytes())
    for name in STATIC_FILES:
        atomic_write_bytes(out.root / name, (pkg / name).read_bytes())
    return [_name(out, "index"), *STATIC_FILES]


def _name(out: StageFolder, key: str) -> str:
    """File ``key``'s name relative to the folder (what the page and the config refer to)."""
    return out.path(key).relative_to(out.root).as_posix()


def build_viewer(model_path: str | Path, out: StageFolder, views_json: str | Path | dict | None = None,
                 canonical: str | Path | Gaussians | None = None, background: Sequence[float] | None = None,
                 fps: float = 12.0, embed: bool = True, title: str = "anigs") -> dict[str, Any]:
    """Write the viewer folder ``out`` (the view stage's ``Outputs``) for ``model_path`` (an update
    stage's model file, or a .anigs compact file).

    Args:
        views_json: the views stage's queue (the viewer starts at its first camera).
        canonical: canonical PLY (or Gaussians) that the model was trained on.
        background: RGB in [0,1] behind the splats (default: the final renders' sky colour).
        embed: also write the embedded scene so the page works when opened from the file system.
    Returns:
        a summary: files, sizes in bytes, Gaussian counts.
    """
    out.root.mkdir(parents=True, exist_ok=True)
    g, deformation, model_cfg = load_animated(model_path, canonical)
    bg = [float(x) for x in (background if background is not None else DEFAULT_BACKGROUND)]
    if len(bg) != 3 or not all(0.0 <= x <= 1.0 for x in bg):
        raise ValueError(f"background must be 3 values in [0,1], got {bg}")
    blob = encode_compact(g, deformation, fps, extra={"source": str(model_path), "config": model_cfg})
    atomic_write_bytes(out.path("scene"), blob)
    files = copy_static(out) + [_name(out, "scene"), _name(out, "config")]
    if embed:
        with atomic_path(out.path("embed")) as tmp, open(tmp, "wb") as fh:
            fh.write(b'window.ANIGS_SCENE_B64 = "')
            fh.write(base64.b64encode(blob))
            fh.write(b'";\n')
        files.append(_name(out, "embed"))
    elif out.path("embed").exists():
        out.path("embed").unlink()  # a stale copy would show an old scene from file://
    cfg = dict(views_config(views_json), title=title, background=bg, fps=float(fps), data=_name(out, "scene"),
               embedded=_name(out, "embed") if embed else None)
    atomic_write_text(out.path("config"), "window.ANIGS_CONFIG = " + json.dumps(cfg, indent=1) + ";\n")
    summary = {"out": str(out.root), "files": sorted(files), "scene_bytes": len(blob),
               "folder_bytes": sum((out.root / f).stat().st_size for f in files),
               "num_gaussians": g.num, "num_dynamic": deformation.num_dynamic, "num_views": len(cfg["views"])}
    log.info("viewer: %d Gaussians (%d moving), scene %.2f MB, %d views -> %s", g.num, deformation.num_dynamic,
             len(blob) / 1e6, len(cfg["views"]), out.root)
    return summary
