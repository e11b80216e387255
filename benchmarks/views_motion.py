"""Views judged where the motion is: each queued view's moving-region sharpness against the photos and
its unobserved pixels, from a results tree; a contact sheet to look at.

    python benchmarks/views_motion.py RESULTS/SCENE [--views VIEWS.json] [--sheet OUT.png]

``RESULTS/SCENE`` holds ``static/``, ``effects/`` and ``sfm/`` (the stages' folders); ``--views``
another queue to judge (default ``views/views.json``: e.g. an older version's queue, measured
with this version's figures). Prints per view: where it stands (a location or a photo's pose),
``content``, ``motion_sharpness`` (``anigs.views.motion``), the reference photo and its sampling
ratio, and the share of unobserved pixels; then the counts against ``views.min_motion_sharpness``
and ``views.max_unobserved`` and the queue's advice. The sheet shows each view's render on grey,
the moving region outlined in magenta and the unobserved pixels in red.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from anigs.cameras import Camera, load_cameras  # noqa: E402
from anigs.gaussians import load_ply  # noqa: E402
from anigs.views import ViewsConfig  # noqa: E402
from anigs.views.content import render_rgb  # noqa: E402
from anigs.views.motion import MotionSharpness, moving_and_holes  # noqa: E402

GREY = (0.5, 0.5, 0.5)


def tile(rgb: np.ndarray, moving: np.ndarray, holes: np.ndarray, lines: list[str]) -> np.ndarray:
    """uint8 BGR: the render with the moving region outlined and holes tinted, captioned."""
    img = cv2.cvtColor((np.clip(rgb, 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
    img[holes] = (0.5 * img[holes] + 0.5 * np.array([0, 0, 255])).astype(np.uint8)
    contours, _ = cv2.findContours(moving.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(img, contours, -1, (255, 0, 255), 1)
    cap = np.full((16 * len(lines) + 4, img.shape[1], 3), 255, np.uint8)
    for i, line in enumerate(lines):
        cv2.putText(cap, line, (3, 13 + 16 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([img, cap])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", type=Path, help="a scene's results folder (static/, effects/, sfm/, views/)")
    ap.add_argument("--views", type=Path, help="the queue to judge (default: SCENE/views/views.json)")
    ap.add_argument("--sheet", type=Path, help="write the contact sheet here")
    ap.add_argument("--title", default="", help="the sheet's title")
    a = ap.parse_args(argv)
    views = json.loads((a.views or a.scene / "views" / "views.json").read_text())
    cfg = ViewsConfig.from_dict(views.get("config") or {})
    g = load_ply(a.scene / "static" / "canonical.ply")
    roi = np.load(a.scene / "effects" / "dynamic.npy").astype(bool)
    cameras = load_cameras(a.scene / "sfm" / "cameras.json")
    motion = MotionSharpness(g, roi, cameras, a.scene / "sfm" / "images", 2 * max(cfg.width, cfg.height))
    tiles, low, holes_over = [], 0, 0
    print(f"{'view':5} {'stands at':18} {'content':>7} {'motion':>6} {'reference':>14} {'k':>5} {'unobserved':>10}")
    for v in views["views"]:
        cam = Camera.from_dict(v["camera"])
        rgb = render_rgb(g, cam, GREY)
        fig = motion.measure(cam, rgb)  # this version's figures, whatever version wrote the queue
        moving, holes = moving_and_holes(g, roi, cam)
        ms = fig["motion_sharpness"]
        low += ms is not None and ms < cfg.min_motion_sharpness
        holes_over += fig["unobserved"] > cfg.max_unobserved
        where = f"photo {v['photo_pose']}" if v.get("photo_pose") else f"location {v['location']} yaw {v['yaw']:+.0f}"
        print(f"{v['id']:5} {where:18} {v['content']:7.2f} {'-' if ms is None else f'{ms:.2f}':>6} "
              f"{fig['motion_reference'] or '-':>14} {fig['motion_scale'] or 0:5.2f} {100 * fig['unobserved']:9.1f}%")
        tiles.append(tile(rgb, moving, holes, [f"{v['id']} {where}", f"motion {'-' if ms is None else f'{ms:.2f}'} "
                                               f"content {v['content']:.2f} unobserved {100 * fig['unobserved']:.1f}%"]))
    n = len(views["views"])
    print(f"{n} views: {low} under min_motion_sharpness {cfg.min_motion_sharpness:g}, {holes_over} over max_unobserved "
          f"{cfg.max_unobserved:g}")
    advice = (views.get("motion") or {}).get("advice")
    print("advice:", advice or "none")
    if a.sheet and tiles:
        cols = 4
        blank = np.full_like(tiles[0], 255)
        tiles += [blank] * (-len(tiles) % cols)
        grid = np.vstack([np.hstack(tiles[i:i + cols]) for i in range(0, len(tiles), cols)])
        head = np.full((24, grid.shape[1], 3), 255, np.uint8)
        cv2.putText(head, a.title or str(a.scene), (4, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        a.sheet.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(a.sheet), np.vstack([head, grid]))
        print("sheet:", a.sheet)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
