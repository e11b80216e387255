"""Contact sheet of a run's final views: what a person deciding to keep a clip sees.

    python benchmarks/contact_sheet.py results/demo [--variant full] [--out PNG] [--scale 2]

One row per final clip (``{scene}/{variant}/final/clips/{view}.npz``): the first frame, the last
frame, the dynamic mask tinted over the first frame (the masks stage's), and the heat
map of the largest change from frame 0 (:func:`anigs.metrics.contact.heat_colours`). Under each
row: the view's figures from the views stage's queue (scene coverage, content and the share of
pixels left out of it as magnified beyond the photos' sampling, edge share, pitch)
and the edge share of the clip's first frame (:func:`anigs.views.content.edge_share`). Prints one
line per view with the same numbers. Default output: ``{scene}/{variant}/contact_final.png``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from anigs.io import atomic_path
from anigs.metrics.contact import MASK_COLOURS, heat_colours, load_rows, max_change, tint
from anigs.stages.final import Outputs as FinalOutputs
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.views.content import edge_share


def _u8(img: np.ndarray, scale: int) -> np.ndarray:
    out = (np.clip(img, 0, 1) * 255).round().astype(np.uint8)
    return cv2.resize(out, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST) if scale > 1 else out


def _caption(text: str, width: int) -> np.ndarray:
    block = np.full((22, width, 3), 255, np.uint8)
    cv2.putText(block, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return block


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene_dir", type=Path, help="results/{scene}")
    ap.add_argument("--variant", default="full")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--scale", type=int, default=2, help="pixel zoom of each panel")
    args = ap.parse_args()
    sd = args.scene_dir
    rows = load_rows(FinalOutputs(sd / args.variant / "final").path("clips"), MasksOutputs(sd / "masks"))
    views = {v["id"]: v for v in ViewsOutputs(sd / "views").report()["views"]}
    parts = []
    for row in rows:
        clip = row.clip
        first, last = clip[0], clip[-1]
        mask = row.dynamic if row.dynamic is not None else np.zeros(first.shape[:2], bool)
        panels = [first, last, tint(first, mask, MASK_COLOURS[0]), heat_colours(max_change(clip))]
        strip = np.concatenate([_u8(p, args.scale) for p in panels], 1)
        v = views.get(row.name, {})
        es = edge_share(first)
        txt = (f"{row.name}: coverage {v.get('coverage', float('nan')):.2f}  content "
               f"{v.get('content') if v.get('content') is None else round(v['content'], 2)}"
               + (f" (magnified {v['magnified']:.2f})" if v.get("magnified") is not None else "") + "  edge share (view) "
               f"{v.get('edge_share') if v.get('edge_share') is None else round(v['edge_share'], 2)}  "
               f"(first frame) {es:.2f}  pitch {v.get('pitch', float('nan')):+.0f}  mask {mask.mean():.2f}")
        print(txt)
        parts += [strip, _caption(txt + "   [first | last | mask | max change]", strip.shape[1])]
    sheet = np.concatenate(parts, 0)
    out = args.out or sd / args.variant / "contact_final.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        if not cv2.imwrite(str(tmp), sheet[..., ::-1]):
            raise RuntimeError(f"could not write {out}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
