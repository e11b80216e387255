"""When no placed view shows the motion sharply: views at the photos' own poses, and advice.

Directions that fail :attr:`ViewsConfig.min_motion_sharpness` at every location they were tried
(:mod:`anigs.views.motion`) leave the queue short. :func:`photo_pose_slots` fills those slots
with views at the poses of the photos that show the moving region best (the fit is sharpest
where the photos looked), and :func:`motion_advice` says which part of the moving region no
view shows sharply, how the photos see it, and where more photos would help. Both go to
``views.json`` (``motion``), the log, the top-down map and ``final.json``.
"""
from __future__ import annotations

import logging
import math
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render.visibility import blend_weights
from anigs.views.candidates import azimuth_deg
from anigs.views.content import ContentCheck
from anigs.views.coverage import scene_coverage
from anigs.views.motion import MIN_WEIGHT, MotionSharpness, photo_pose_view
from anigs.views.place import Placed, Slot

log = logging.getLogger("anigs.views")

MAX_TRIED = 24      # photo poses measured at most (those with the largest moving region first)
SEEN_SHARE = 0.1    # a photo sees a region when it sees >= this share of its Gaussians


def _yaw_pitch(cam: Camera, heading_deg: float, up: np.ndarray) -> tuple[float, float]:
    """(yaw relative to ``heading_deg``, pitch) of ``cam``'s forward direction, in degrees."""
    f = cam.forward
    yaw = (float(azimuth_deg(f, up)) - heading_deg + 180.0) % 360.0 - 180.0
    return yaw, math.degrees(math.asin(float(np.clip(f @ up, -1.0, 1.0))))


def photo_pose_slots(motion: MotionSharpness, check: ContentCheck, g_obs: Gaussians, cand: np.ndarray,
                     heading: np.ndarray, up: np.ndarray, missing: Sequence[float], first_location: int,
                     width: int, height: int, coverage_alpha: float
                     ) -> tuple[list[Slot], dict[int, dict[str, Any]]]:
    """(slots, their figures by camera ``id``): up to one view per ``missing`` yaw at the pose of a
    photo that shows the moving region (``motion.photos``) and passes ``min_motion_sharpness``
    there (none passes: the sharpest one alone), chosen greedily for the moving Gaussians not yet
    shown, weighted by the view's motion sharpness. Each slot's candidate is the one nearest the
    photo; locations count on from ``first_location``."""
    photos = sorted(motion.photos, key=lambda p: -int(p.moving.sum()))[:MAX_TRIED]
    tried = []
    for p in photos:
        cam = photo_pose_view(p.camera, width, height)
        fig = {**check.measure(cam), "photo_pose": p.camera.name}
        tried.append((cam, fig, p.seen))
    sharp_enough = [t for t in tried if (t[1].get("motion_sharpness") or 0.0) >= check.rule.min_motion_sharpness]
    if not sharp_enough and tried:  # no photo pose reaches the bar either: the sharpest one alone
        sharp_enough = [max(tried, key=lambda t: t[1].get("motion_sharpness") or 0.0)]
    tried = sharp_enough
    shown = np.zeros_like(motion.roi)
    slots: list[Slot] = []
    figures: dict[int, dict[str, Any]] = {}
    for k, yaw in enumerate(missing):
        scores = [float((seen & ~shown).sum()) * max(fig.get("motion_sharpness") or 0.0, 1e-3)
                  for cam, fig, seen in tried]
        if not tried or max(scores) <= 0:
            break
        cam, fig, seen = tried.pop(int(np.argmax(scores)))
        shown |= seen
        ci = int(np.argmin(np.linalg.norm(cand - cam.center, axis=1)))
        y, pitch = _yaw_pitch(cam, float(heading[ci]), up)
        slots.append(Slot(first_location + k, ci, float(yaw), Placed(cam, scene_coverage(g_obs, cam, coverage_alpha), y,
                                                                      pitch)))
        figures[id(cam)] = fig
    return slots, figures


def motion_advice(motion: MotionSharpness, failed: Sequence[tuple[Camera, dict[str, Any]]], missing: int,
                  min_sharpness: float, fallback: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """What no view shows sharply and where more photos would help (None: no direction failed
    for motion sharpness). ``failed``: (camera, figures) of the directions tried that failed it;
    ``missing``: the directions placed nowhere; ``fallback``: the figures of the photo-pose views
    that replaced them."""
    if not failed:
        return None
    g = motion.g
    region = np.zeros(g.num, bool)
    for cam, _ in failed:
        region |= (blend_weights(g, cam)[0] >= MIN_WEIGHT) & motion.roi
    if not region.any():
        return None
    means = g.means.detach().double().numpy()[region]
    lo, centre, hi = np.percentile(means, [10, 50, 90], axis=0)
    seeing = [p.camera.name for p in motion.photos if (p.seen & region).sum() >= SEEN_SHARE * region.sum()]
    scale = float(np.median([f["motion_scale"] for _, f in failed if f.get("motion_scale") is not None] or [0.0]))
    best = max((f.get("motion_sharpness") or 0.0 for f in fallback), default=None)
    text = (f"no view shows the moving region around ({centre[0]:.2f}, {centre[1]:.2f}, {centre[2]:.2f}) "
            f"({int(region.sum())} moving Gaussians, seen in {len(seeing)} photos) as sharply as the photos do: "
            f"{missing} direction(s) were placed nowhere, {len(failed)} tried under min_motion_sharpness "
            f"{min_sharpness:g}. ")
    if not seeing:
        text += "No photo shows it well enough to compare: photograph it, facing it, from a few positions."
    elif scale > 1.0:
        text += (f"The views stand closer to it than the photos (they sample it {scale:.1f}x finer than the best "
                 "photo) and magnify what the photos resolved: more photos of it from closer, facing it, would let "
                 "views show it sharply.")
    else:
        text += ("The photos sample it as finely as the views do (median " f"{scale:.2f} of the views' pixel size), so "
                 "the static fit is coarser there than the photos: a higher static.budget (more steps and Gaussians) "
                 "would help first, more photos of it from closer next.")
    if fallback:
        text += (f" The queue shows it from the poses of photos {', '.join(f['photo_pose'] for f in fallback)} "
                 f"instead (motion sharpness up to {best:.2f}).")
    return {"advice": text, "centre": centre.tolist(), "box_10_90": [lo.tolist(), hi.tolist()],
            "moving_gaussians": int(region.sum()), "directions_missing": missing, "directions_failed": len(failed),
            "median_motion_scale": scale, "photos_seeing": seeing,
            "photo_poses": [f["photo_pose"] for f in fallback], "best_photo_pose_sharpness": best}
