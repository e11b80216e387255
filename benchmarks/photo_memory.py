"""Peak memory of holding a capture's photos the way the static fit holds them, before and after
issue 28 (float32 twice -> uint8 once). One mode per process, so each peak is its own.

    python benchmarks/photo_memory.py IMAGES CAMERAS.json after
    python benchmarks/photo_memory.py IMAGES CAMERAS.json before   # float32 + the fit's old clamped copy

Prints JSON: photos, peak RSS (MiB), RSS before loading (Python + torch), MiB held.
"""
from __future__ import annotations

import json
import resource
import sys


def main(images: str, cameras: str, mode: str) -> dict:
    import torch

    from anigs.images import load_inputs

    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if mode == "before":
        imgs, _ = load_inputs(images, cameras)
        held = [im.detach().float().clamp(0, 1) for im in imgs]  # fit_static's copy before the change
        held_mib = sum(t.numel() * t.element_size() for t in imgs + held) / 2**20
    elif mode == "after":
        imgs, _ = load_inputs(images, cameras, compact=True)
        held = [im.detach() if im.dtype == torch.uint8 else im.float().clamp(0, 1) for im in imgs]
        held_mib = sum(t.numel() * t.element_size() for t in held) / 2**20
    else:
        raise SystemExit(f"mode must be before or after, got {mode!r}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"mode": mode, "photos": len(imgs), "peak_rss_mib": round(peak), "rss_before_loading_mib": round(base),
            "held_mib": round(held_mib)}


if __name__ == "__main__":
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    print(json.dumps(main(*sys.argv[1:])))
