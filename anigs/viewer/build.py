"""``build_viewer``: a self-contained viewer folder for an animated scene.

The folder (open ``index.html`` directly, or serve it with ``anigs view --serve``)::

    index.html viewer.css *.js   the WebGL2 viewer (package data anigs/viewer/static, no CDN)
    config.js                    window.ANIGS_CONFIG: queued views, up, background, fps
    scene.anigs                  the compact animated scene (anigs.viewer.compact)
    scene.js                     the same bytes base64-encoded (``embed``): pages opened from
                                 file:// cannot fetch(), they load this script instead
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
from anigs.io import atomic_path, atomic_write_bytes, atomic_write_text, read_json
from anigs.viewer.compact import decode_compact, encode_compact
from anigs.views import cameras_from_views

log = logging.getLogger("anigs.viewer")

DEFAULT_BACKGROUND = (0.62, 0.76, 0.92)  # the final renders' default sky colour (final.background)
STATIC_FILES = ("index.html", "viewer.css", "format.js", "sort-worker.js", "shaders.js", "renderer.js",
                "camera.js", "viewer.js", "ui.js")
SCENE_FILE, EMBED_FILE, CONFIG_FILE = "scene.anigs", "scene.js", "config.js"


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


def copy_static(out_dir: Path) -> list[str]:
    """Copy the viewer's HTML/JS/CSS from the package data into ``out_dir``."""
    pkg = resources.files("anigs.viewer") / "static"
    for name in STATIC_FILES:
        atomic_write_bytes(out_dir / name, (pkg / name).read_bytes())
    return list(STATIC_FILES)


def build_viewer(model_path: str | Path, out_dir: str | Path, views_json: str | Path | dict | None = None,
                 canonical: str | Path | Gaussians | None = None, background: Sequence[float] | None = None,
                 fps: float = 12.0, embed: bool = True, title: str = "anigs") -> dict[str, Any]:
    """Write the viewer folder for ``model_path`` (model.pt, or a .anigs compact file).

    Args:
        views_json: views.json of the views stage (the viewer starts at its first camera).
        canonical: canonical PLY (or Gaussians) that model.pt was trained on.
        background: RGB in [0,1] behind the splats (default: the final renders' sky colour).
        embed: also write scene.js so index.html works when opened from the file system.
    Returns:
        a summary: files, sizes in bytes, Gaussian counts.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    g, deformation, model_cfg = load_animated(model_path, canonical)
    bg = [float(x) for x in (background if background is not None else DEFAULT_BACKGROUND)]
    if len(bg) != 3 or not all(0.0 <= x <= 1.0 for x in bg):
        raise ValueError(f"background must be 3 values in [0,1], got {bg}")
    blob = encode_compact(g, deformation, fps, extra={"source": str(model_path), "config": model_cfg})
    atomic_write_bytes(out / SCENE_FILE, blob)
    files = copy_static(out) + [SCENE_FILE, CONFIG_FILE]
    if embed:
        with atomic_path(out / EMBED_FILE) as tmp, open(tmp, "wb") as fh:
            fh.write(b'window.ANIGS_SCENE_B64 = "')
            fh.write(base64.b64encode(blob))
            fh.write(b'";\n')
        files.append(EMBED_FILE)
    elif (out / EMBED_FILE).exists():
        (out / EMBED_FILE).unlink()  # a stale copy would show an old scene from file://
    cfg = dict(views_config(views_json), title=title, background=bg, fps=float(fps), data=SCENE_FILE,
               embedded=EMBED_FILE if embed else None)
    atomic_write_text(out / CONFIG_FILE, "window.ANIGS_CONFIG = " + json.dumps(cfg, indent=1) + ";\n")
    summary = {"out": str(out), "files": sorted(files), "scene_bytes": len(blob),
               "folder_bytes": sum((out / f).stat().st_size for f in files),
               "num_gaussians": g.num, "num_dynamic": deformation.num_dynamic, "num_views": len(cfg["views"])}
    log.info("viewer: %d Gaussians (%d moving), scene %.2f MB, %d views -> %s", g.num, deformation.num_dynamic,
             len(blob) / 1e6, len(cfg["views"]), out)
    return summary
