"""Top-down picture of a view plan: scene points, ROI, candidates, chosen locations, frusta.

People look at this before spending GPU hours: it shows where the views stand and what
they see. Drawn with OpenCV on the plane orthogonal to the plan's ``up``.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import cv2
import numpy as np

from anigs.io import atomic_path
from anigs.geometry import horizontal_basis
from anigs.views.plan import ViewPlan

# BGR colours
_REJECTED = (40, 40, 140)
_NO_CONTENT = (0, 120, 230)  # rejected by the content test (anigs.views.content): orange
_DROPPED = (150, 150, 40)
_BLURRED = (160, 40, 160)    # rejected by the motion-sharpness test (anigs.views.motion): purple
_ADVICE = (30, 30, 200)
_DIR_COLOURS = [(200, 90, 20), (0, 140, 255), (180, 40, 180), (40, 160, 40), (30, 30, 200)]


def draw_topdown(plan: ViewPlan, means: np.ndarray, roi: np.ndarray, size: int = 720,
                 max_points: int = 20000, seed: int = 0) -> np.ndarray:
    """Render the plan as a uint8 BGR image [size,size,3].

    Args:
        means: Gaussian centres [N,3]; roi: bool [N] dynamic Gaussians.
    """
    e1, e2 = horizontal_basis(plan.up)
    to2 = lambda p: np.stack([np.asarray(p) @ e1, np.asarray(p) @ e2], -1)  # noqa: E731
    pts, cand = to2(means), to2(plan.candidates)
    rng = np.random.default_rng(seed)
    if len(pts) > max_points:
        keep = np.sort(rng.choice(len(pts), max_points, replace=False))
        pts, roi = pts[keep], roi[keep]
    # frame: candidates + ROI (+ robust extent of the rest)
    core = [cand, to2(plan.roi_centroid)[None]]
    if roi.any():
        core.append(pts[roi])
    allp = np.concatenate(core)
    lo, hi = np.percentile(allp, 1, 0), np.percentile(allp, 99, 0)
    lo, hi = np.minimum(lo, cand.min(0)), np.maximum(hi, cand.max(0))
    span = float(max(hi - lo)) or 1.0
    margin = 0.12 * span
    lo, span = lo - margin, span + 2 * margin
    advice = (plan.motion or {}).get("advice")
    advice_lines = textwrap.wrap("ADVICE: " + advice, size // 7) if advice else []
    footer = 78 + 16 * len(advice_lines)
    img = np.full((size + footer, size, 3), 255, np.uint8)

    def px(p: np.ndarray) -> np.ndarray:
        q = (np.asarray(p) - lo) / span * (size - 1)
        return np.stack([q[..., 0], (size - 1) - q[..., 1]], -1)  # image y grows down: flip

    def ipt(p) -> tuple[int, int]:
        q = px(p)
        return int(round(float(q[0]))), int(round(float(q[1])))

    for sel, col in ((~roi, (200, 200, 200)), (roi, (60, 170, 60))):
        q = np.round(px(pts[sel])).astype(int)
        ok = (q[:, 0] >= 0) & (q[:, 0] < size) & (q[:, 1] >= 0) & (q[:, 1] < size)
        img[q[ok, 1], q[ok, 0]] = col
    for c in cand:
        cv2.circle(img, ipt(c), 4, (120, 120, 120), 1, cv2.LINE_AA)
    cx, cy = ipt(to2(plan.roi_centroid))
    cv2.drawMarker(img, (cx, cy), (0, 100, 0), cv2.MARKER_CROSS, 16, 2)
    ray = 0.18 * span
    yaws = list(dict.fromkeys(v["yaw"] for v in plan.views))
    for v, cam in zip(plan.views, plan.cameras):
        eye = to2(cam.center)
        half = math.radians(cam.fov_x) / 2
        fwd = to2(cam.forward)
        n = np.linalg.norm(fwd)
        if n < 1e-9:
            continue
        fwd /= n
        a = math.atan2(fwd[1], fwd[0])
        col = _DIR_COLOURS[yaws.index(v["yaw"]) % len(_DIR_COLOURS)]
        left = eye + ray * np.array([math.cos(a + half), math.sin(a + half)])
        right = eye + ray * np.array([math.cos(a - half), math.sin(a - half)])
        poly = np.round(px(np.stack([eye, left, right]))).astype(np.int32)
        cv2.polylines(img, [poly], True, col, 1, cv2.LINE_AA)
        tip = eye + 0.6 * ray * fwd
        cv2.arrowedLine(img, ipt(eye), ipt(tip), col, 2 if v.get("photo_pose") else 1, cv2.LINE_AA, tipLength=0.15)
        if v.get("motion_sharpness") is not None:  # the moving region's sharpness against the photos'
            t = ipt(tip)
            cv2.putText(img, f"{v['motion_sharpness']:.2f}", (t[0] + 3, t[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, col,
                        1, cv2.LINE_AA)
    for r in plan.rejected:  # directions that failed the coverage test: short dark-red ray ending in an x
        eye = to2(np.asarray(r["position"]))
        fwd = to2(np.asarray(r["forward"]))
        n = np.linalg.norm(fwd)
        if n < 1e-9:
            continue
        tip = eye + 0.45 * ray * fwd / n
        reason = str(r.get("reason", ""))
        col = (_BLURRED if "motion sharpness" in reason else
               _NO_CONTENT if reason.startswith(("content", "edge", "unobserved")) else _REJECTED)
        cv2.line(img, ipt(eye), ipt(tip), col, 1, cv2.LINE_AA)
        cv2.drawMarker(img, ipt(tip), col, cv2.MARKER_TILTED_CROSS, 7, 1, cv2.LINE_AA)
    for d in plan.dropped:  # views left out for a negligible dynamic region: short ray ending in a circle
        eye, fwd = to2(np.asarray(d["position"])), to2(np.asarray(d["forward"]))
        n = np.linalg.norm(fwd)
        if n < 1e-9:
            continue
        tip = eye + 0.45 * ray * fwd / n
        cv2.line(img, ipt(eye), ipt(tip), _DROPPED, 1, cv2.LINE_8)
        cv2.circle(img, ipt(tip), 4, _DROPPED, 1, cv2.LINE_8)
    for i, ci in enumerate(plan.chosen):
        p = ipt(cand[ci])
        cv2.circle(img, p, 8, (30, 30, 220), -1, cv2.LINE_AA)
        cv2.putText(img, str(i), (p[0] + 9, p[1] - 9), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (30, 30, 220), 2, cv2.LINE_AA)
    y0 = size + 18
    cv2.putText(img, "grey: scene  green: ROI  o: candidates  red: locations (CCW)  "
                "x: rejected (orange: no content, purple: blurred motion)",
                (8, y0), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    x = 8
    for j, yaw in enumerate(yaws):
        col = _DIR_COLOURS[j % len(_DIR_COLOURS)]
        cv2.putText(img, f"yaw {yaw:+.0f}", (x, y0 + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.45, col, 1, cv2.LINE_AA)
        x += 90
    if plan.layout is not None:
        dropped = f", {len(plan.dropped)} dropped (o: no dynamic region)" if plan.dropped else ""
        n_content = sum(str(r.get("reason", "")).startswith(("content", "edge")) for r in plan.rejected)
        cv2.putText(img, f"layout {plan.layout.kind}, {len(plan.rejected)} rejected ({n_content} for content){dropped}",
                    (8, y0 + 38),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    per_view = [v.get("motion_sharpness") for v in plan.views]
    if any(m is not None for m in per_view):
        n_pose = sum(bool(v.get("photo_pose")) for v in plan.views)
        cv2.putText(img, "motion sharpness vs the photos (at each arrow): " + " ".join(
            "-" if m is None else f"{m:.2f}" for m in per_view) + (f"; {n_pose} at photo poses (thick)" if n_pose else ""),
            (8, y0 + 56), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    for i, line in enumerate(advice_lines):
        cv2.putText(img, line, (8, y0 + 74 + 16 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.42, _ADVICE, 1, cv2.LINE_AA)
    if plan.coverage_after:
        cv2.putText(img, f"ROI coverage {100 * plan.coverage_after[-1]:.1f}% after {len(plan.views)} views",
                    (x + 10, y0 + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def save_topdown(path: str | Path, plan: ViewPlan, means: np.ndarray, roi: np.ndarray, size: int = 720) -> None:
    """Draw and write the top-down PNG atomically."""
    img = draw_topdown(plan, means, roi, size)
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise RuntimeError(f"could not write {path}")
