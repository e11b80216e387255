"""What the static-fit cost benchmarks share: an SfM folder's photos and cameras, and a photo resized
with its camera (area interpolation).

    from _scaled_capture import load_sfm_capture, scaled_view   # benchmarks/ is on sys.path when a script runs
"""
from __future__ import annotations

import argparse

import torch
import torch.nn.functional as F


def load_sfm_capture(ap: argparse.ArgumentParser) -> tuple[argparse.Namespace, object, list, list]:
    """Parse ``ap`` (after adding ``--threads``), set torch's threads, and load the ``--sfm`` folder:
    (args, its Outputs, photos float [H,W,3], cameras)."""
    from anigs.images import load_inputs
    from anigs.stages.sfm import Outputs as SfmOutputs

    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sfm = SfmOutputs(args.sfm)
    imgs, cams = load_inputs(sfm.path("images"), sfm.path("cameras"))
    return args, sfm, imgs, cams


def scaled_view(im: torch.Tensor, cam, scale: float, min_side: int = 1) -> tuple[torch.Tensor, object]:
    """Photo ``im`` float [H,W,3] and its camera at ``scale`` (each side at least ``min_side``): the
    photo resized by area interpolation, float [h,w,3], and ``cam.scaled(w, h)``."""
    w, h = max(min_side, round(cam.width * scale)), max(min_side, round(cam.height * scale))
    x = F.interpolate(im.permute(2, 0, 1)[None].float(), size=(h, w), mode="area")[0].permute(1, 2, 0)
    return x, cam.scaled(w, h)
