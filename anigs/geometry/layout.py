"""Capture layout (:func:`classify_layout`): forward-facing, orbit (inward) or walk."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.geometry.basics import horizontal_basis, unit

log = logging.getLogger("anigs.geometry")

LAYOUTS = ("forward", "orbit", "walk")


@dataclass
class Layout:
    """Capture layout: ``kind`` (forward | orbit | walk) and the measurements behind it."""

    kind: str
    metrics: dict[str, float]
    focus: np.ndarray | None = None    # [3] where the optical axes meet (orbit / forward), else None

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "metrics": {k: float(v) for k, v in self.metrics.items()},
                "focus": None if self.focus is None else [float(v) for v in self.focus]}


def rays_meet(origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares point [D] nearest to the lines ``origins + t dirs`` ([C,D]) and the
    conditioning (smallest / largest eigenvalue of the normal matrix, 0 = parallel lines)."""
    d = unit(dirs)
    D = d.shape[1]
    P = np.eye(D)[None] - d[:, :, None] * d[:, None, :]
    A = P.sum(0)
    b = np.einsum("cij,cj->i", P, origins)
    ev = np.linalg.eigvalsh(A)
    q = np.linalg.lstsq(A, b, rcond=None)[0]
    return q, float(ev[0] / max(ev[-1], 1e-12))


def axis_hits(cameras: Sequence[Camera], points: np.ndarray, cone_deg: float = 6.0, quantile: float = 0.1,
              max_points: int = 20000) -> np.ndarray:
    """Per camera: depth [C] of the first content along its optical axis (``quantile`` of the
    depths of the points within ``cone_deg`` of the axis, occlusion ignored); NaN when none."""
    P = np.asarray(points, np.float64)
    if len(P) > max_points:
        P = P[np.linspace(0, len(P) - 1, max_points).astype(int)]
    out = np.full(len(cameras), np.nan)
    cos_c = math.cos(math.radians(cone_deg))
    for i, cam in enumerate(cameras):
        d = P - cam.center
        z = d @ cam.forward
        r = np.linalg.norm(d, axis=1)
        sel = (z > 0) & (z >= cos_c * r)
        if sel.sum() >= 5:
            out[i] = float(np.quantile(z[sel], quantile))
    return out


def classify_layout(cameras: Sequence[Camera], up: np.ndarray, points: np.ndarray | None = None,
                    forward_resultant: float = 0.75, forward_span_deg: float = 150.0,
                    orbit_span_deg: float = 180.0, orbit_facing_deg: float = 35.0,
                    orbit_hit_ratio: float = 1.3) -> Layout:
    """Forward-facing, inward orbit or walk-through/outward from camera poses (+ content points).

    Metrics (horizontal, in the plane orthogonal to ``up``): ``resultant`` = length of the mean
    unit viewing direction (1: all look the same way); the point where the optical axes meet
    (``focus``); ``span_deg`` = how far the cameras reach around it (360 minus the largest
    azimuth gap); ``facing_deg`` = median angle between a camera's direction and the
    direction to the focus; ``hit_ratio`` = median over cameras of the depth of the first
    content along the optical axis (:func:`axis_hits`) / the distance to the focus (an orbit
    looks at an object standing at the focus: <= 1; a loop looking across an open lawn sees
    the far side: > 1).

    forward: resultant >= ``forward_resultant`` and span < ``forward_span_deg``;
    orbit: span >= ``orbit_span_deg``, facing <= ``orbit_facing_deg`` and (with points) hit_ratio
    <= ``orbit_hit_ratio``; walk: everything else (cameras among the content, looking outwards).
    """
    e1, e2 = horizontal_basis(unit(up))
    if len(cameras) < 2:
        return Layout("walk", {"num_cameras": float(len(cameras))})
    C = np.stack([c.center for c in cameras])
    F = np.stack([c.forward for c in cameras])
    c2 = np.stack([C @ e1, C @ e2], 1)
    f2 = np.stack([F @ e1, F @ e2], 1)
    ok = np.linalg.norm(f2, axis=1) > 1e-3
    if ok.sum() < 2:
        return Layout("walk", {"num_cameras": float(len(cameras)), "horizontal_views": float(ok.sum())})
    c2, f2 = c2[ok], unit(f2[ok])
    resultant = float(np.linalg.norm(f2.mean(0)))
    q, cond = rays_meet(c2, f2)
    to_q = q - c2
    facing = np.degrees(np.arccos(np.clip((unit(to_q) * f2).sum(1), -1, 1)))
    az = np.sort(np.arctan2(-to_q[:, 1], -to_q[:, 0]))
    gaps = np.diff(np.concatenate([az, az[:1] + 2 * math.pi]))
    span = float(360.0 - math.degrees(gaps.max())) if len(az) > 1 else 0.0
    ring = float(np.median(np.linalg.norm(to_q, axis=1)))
    metrics = {"resultant": resultant, "span_deg": span, "facing_deg": float(np.median(facing)),
               "ring_radius": ring, "conditioning": cond, "num_cameras": float(len(cameras))}
    hit = float("nan")
    if points is not None and len(points) >= 10:
        cams_ok = [c for c, o in zip(cameras, ok) if o]
        depth = axis_hits(cams_ok, points)
        dist = np.linalg.norm(to_q, axis=1)
        good = np.isfinite(depth) & (dist > 1e-9)
        hit = float(np.median(depth[good] / dist[good])) if good.any() else float("inf")
        metrics["hit_ratio"] = hit
    if resultant >= forward_resultant and span < forward_span_deg:
        kind = "forward"
    elif (span >= orbit_span_deg and metrics["facing_deg"] <= orbit_facing_deg
          and (math.isnan(hit) or hit <= orbit_hit_ratio)):
        kind = "orbit"
    else:
        kind = "walk"
    focus = None
    if kind != "walk":
        hmed = float(np.median(C @ unit(up)))
        focus = q[0] * e1 + q[1] * e2 + hmed * unit(up)
    return Layout(kind, metrics, focus)
