"""A still model: the ``model.pt`` of a scene where nothing moves.

When the effects stage finds nothing to animate, the workflow writes this instead of running
any round: a deformation with an empty dynamic set (so every frame is the canonical scene, bit
for bit) in the same format as a trained model, so that the final renders, the export, the
viewer and the evaluation run unchanged and say why nothing moves.
"""
from __future__ import annotations

from pathlib import Path

import torch

from anigs.animate.deform import DCTDeformation, save_model
from anigs.gaussians import Gaussians


def still_deformation(num_gaussians: int, num_frames: int, num_bases: int) -> DCTDeformation:
    """A DCT deformation of ``num_gaussians`` Gaussians of which none is dynamic (T frames, K bases)."""
    return DCTDeformation(torch.zeros(0, dtype=torch.long), num_frames, num_bases, num_gaussians=num_gaussians)


def write_still_model(canonical_path: str | Path, out: str | Path, num_frames: int, num_bases: int,
                      reason: str) -> dict:
    """Write the still model of the canonical scene at ``canonical_path`` to ``out``; ``reason`` (why
    nothing moves) is stored in the model's ``extra`` and returned with the model's shape."""
    if not reason:
        raise ValueError("write_still_model: say why nothing moves (reason)")
    canonical = Gaussians.load_ply(canonical_path)
    deformation = still_deformation(canonical.num, num_frames, num_bases)
    info = {"still": True, "reason": reason, "num_gaussians": canonical.num, "num_frames": int(num_frames),
            "num_bases": int(num_bases)}
    save_model(out, deformation, canonical, config={"num_frames": int(num_frames), "num_bases": int(num_bases)},
               extra=info)
    return info
