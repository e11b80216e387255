"""Stage ``export``: the animated scene for other tools.

``scene.anigs`` (the compact format of :mod:`anigs.viewer.compact`: the canonical Gaussians once,
DCT motion coefficients of the moving ones only; ``load_compact(path).frame(t)`` reproduces the
library's frame t exactly), ``animated.ply`` (the standard 3DGS PLY plus per-Gaussian DCT
properties) with its JSON sidecar, and with ``frames: true`` the per-frame PLY sequence.
"""
from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.export")

COMPACT_FILE = "scene.anigs"  # the compact animated scene (anigs.viewer.compact): canonical once, motion of the moving


@dataclass
class ExportConfig:
    """``export`` config section."""

    frames: bool = False  # also write the per-frame PLY sequence (scene.anigs holds every frame exactly)
    frame_step: int = 1  # every n-th frame of 0..T-1
    fps: float = 12.0

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "ExportConfig":
        cfg = from_dict(ExportConfig, d, "export", KeyError)
        if cfg.frame_step < 1:
            raise ValueError(f"export.frame_step must be >= 1, got {cfg.frame_step}")
        return cfg


Config = ExportConfig  # the `export` config section


def run(canonical_path: str | Path, model_path: str | Path, out: str | Path, cfg: ExportConfig) -> dict:
    """Export the model at ``model_path`` into ``out``; returns the ``animated.json`` sidecar."""
    from anigs.animate.deform import load_model
    from anigs.export import save_animated_ply, sidecar
    from anigs.io import write_json
    from anigs.viewer.compact import save_compact, write_frame_plys

    canonical, deformation, _ = load_model(model_path, canonical_path)
    out = Path(out)
    names = write_frame_plys(out, canonical, deformation, cfg.frame_step) if cfg.frames else []
    save_compact(out / COMPACT_FILE, canonical, deformation, cfg.fps)
    extra = save_animated_ply(out / "animated.ply", canonical, deformation)
    meta = sidecar(deformation, cfg.fps, "animated.ply", extra)
    meta["frames"] = names
    meta["compact"] = COMPACT_FILE
    write_json(out / "animated.json", meta)
    log.info("export: %d frame PLYs and animated.ply (%d dynamic of %d Gaussians, K=%d, T=%d) -> %s",
             len(names), deformation.num_dynamic, canonical.num, deformation.num_bases, deformation.num_frames, out)
    return meta


# ---- command line: anigs export ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p, help="canonical 3DGS PLY")
    p.add_argument("--model", required=True, help="trained model.pt")
    add_out(p, "output folder")
    add_params(p, "export")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    run(args.canonical, args.model, args.out, ExportConfig.from_dict(parse_params(args.params)))
    return 0
