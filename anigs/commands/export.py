"""``anigs export``: per-frame 3DGS PLY sequence + compact animated PLY with a JSON sidecar."""
from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

log = logging.getLogger("anigs.export")


@dataclass
class ExportConfig:
    """``export`` config section."""

    frames: bool = True  # write the per-frame PLY sequence
    frame_step: int = 1  # every n-th frame of 0..T-1
    fps: float = 12.0

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "ExportConfig":
        d = dict(d or {})
        unknown = sorted(set(d) - {f.name for f in fields(ExportConfig)})
        if unknown:
            raise KeyError(f"export: unknown key(s) {unknown}")
        return ExportConfig(**d)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--canonical", required=True, help="canonical 3DGS PLY")
    p.add_argument("--model", required=True, help="trained model.pt")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--params", default=None, help="export config section as JSON")


def run(args: argparse.Namespace) -> int:
    from anigs.animated import deformed
    from anigs.cli import parse_params
    from anigs.deform import load_model
    from anigs.export import save_animated_ply, sidecar
    from anigs.io import write_json

    cfg = ExportConfig.from_dict(parse_params(args.params))
    if cfg.frame_step < 1:
        raise ValueError(f"export.frame_step must be >= 1, got {cfg.frame_step}")
    canonical, deformation, _ = load_model(args.model, args.canonical)
    out = Path(args.out)
    names = []
    if cfg.frames:
        import torch

        with torch.no_grad():
            for t in range(0, deformation.num_frames, cfg.frame_step):
                name = f"frames/frame_{t:04d}.ply"
                deformed(canonical, deformation, t).save_ply(out / name)
                names.append(name)
    extra = save_animated_ply(out / "animated.ply", canonical, deformation)
    meta = sidecar(deformation, cfg.fps, "animated.ply", extra)
    meta["frames"] = names
    write_json(out / "animated.json", meta)
    log.info("export: %d frame PLYs and animated.ply (%d dynamic of %d Gaussians, K=%d, T=%d) -> %s",
             len(names), deformation.num_dynamic, canonical.num, deformation.num_bases, deformation.num_frames, out)
    return 0
