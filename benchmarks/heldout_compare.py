"""Side-by-side held-out photos of two static fits of one SfM: photo | fit A | fit B.

    python benchmarks/heldout_compare.py --sfm RESULTS/photos/sfm --static A_static B_static \\
        [--labels before after] [--out sheet.png] [--threads 1]

Each row is one photo the fits held out (``static/metrics.json`` ``holdout``; both fits must hold out
the same photos at the same size), rendered at the fits' photo size on their grey evaluation
background, the PSNR against the photo in each caption. Prints one line per photo.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402

from anigs.gaussians import load_ply  # noqa: E402
from anigs.images import load_inputs  # noqa: E402
from anigs.io import atomic_path  # noqa: E402
from anigs.render import rasterize  # noqa: E402
from anigs.ssim import psnr  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402


def _caption(img: np.ndarray, text: str) -> np.ndarray:
    bar = np.full((26, img.shape[1], 3), 255, np.uint8)
    cv2.putText(bar, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([bar, img], 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True, help="the sfm stage's folder (cameras.json, images/)")
    ap.add_argument("--static", nargs=2, required=True, help="two static stage folders (canonical.ply, metrics.json)")
    ap.add_argument("--labels", nargs=2, default=["A", "B"], help="a caption for each fit")
    ap.add_argument("--out", default="heldout_compare.png", help="the sheet (PNG)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sfm = SfmOutputs(args.sfm)
    imgs, cams = load_inputs(sfm.path("images"), sfm.path("cameras"))
    metrics = [json.loads((Path(s) / "metrics.json").read_text()) for s in args.static]
    if metrics[0]["holdout"] != metrics[1]["holdout"] or metrics[0]["image_size"] != metrics[1]["image_size"]:
        raise SystemExit("the two fits hold out other photos or fit at other sizes: not comparable")
    held, (w, h) = metrics[0]["holdout"], metrics[0]["image_size"]
    fits = [load_ply(str(Path(s) / "canonical.ply")) for s in args.static]
    bg = torch.tensor([0.5, 0.5, 0.5])
    rows = []
    for im, cam in zip(imgs, cams):
        if cam.name not in held:
            continue
        c = cam.scaled(w, h)
        photo = F.interpolate(im.permute(2, 0, 1)[None].float(), size=(h, w), mode="area")[0].permute(1, 2, 0)
        tiles = [_caption((photo.numpy() * 255).round().astype(np.uint8), f"{cam.name}: photo")]
        line = [cam.name]
        for g, label in zip(fits, args.labels):
            with torch.no_grad():
                rgb, _, _ = rasterize(g.means, g.quats, g.log_scales.exp(), torch.sigmoid(g.opacity_logits), g.sh,
                                      c.torch_viewmat(), c.torch_K(), w, h, sh_degree=g.sh_degree, background=bg)
            rgb = rgb.clamp(0, 1)
            p = psnr(rgb, photo)
            line.append(f"{label} {p:.2f} dB")
            tiles.append(_caption((rgb.numpy() * 255).round().astype(np.uint8), f"{label}: {p:.2f} dB"))
        rows.append(np.concatenate(tiles, 1))
        print(", ".join(line), flush=True)
    with atomic_path(args.out) as tmp:
        cv2.imwrite(str(tmp), cv2.cvtColor(np.concatenate(rows, 0), cv2.COLOR_RGB2BGR))
    print(f"sheet: {args.out} (photo | {' | '.join(args.labels)})")


if __name__ == "__main__":
    main()
