"""Up direction of a capture (:func:`estimate_up`); the cues and the fallback are described in :mod:`anigs.geometry`."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.geometry.basics import Z_UP, angle_deg, fibonacci_sphere, roll_axes, unit
from anigs.geometry.planes import plane_cost, point_normals

log = logging.getLogger("anigs.geometry")

ROLL_PRIOR = (0.0, 0.5, 1.5, 0.5)   # cost of roll 0, 90, 180, 270 degrees (gravity cue of photo orientation)


@dataclass
class UpConfig:
    """Weights of the up-direction cues (see module docstring)."""

    residual_deg: float = 10.0    # a camera's horizontal axis may tilt this much (hand-held roll)
    pitch_scale_deg: float = 60.0  # pitch penalty (pitch / scale)^2, capped at 1.5
    roll_prior: tuple = ROLL_PRIOR
    plane_weight: float = 2.0     # weight of the point-cloud plane cue (against the mean per-camera cost)
    min_planarity: float = 0.5    # patches less planar than this are ignored
    min_margin: float = 0.02      # per-camera cost margin below which two solutions are undecidable
    prior_weight: float = 1e-3    # closed-form refinement: weak pull towards the mean image-up axis
    degenerate_ratio: float = 0.02  # 2nd eigenvalue / largest of the horizontal axes' scatter below: one direction free


@dataclass
class UpEstimate:
    """Result of :func:`estimate_up`."""

    up: np.ndarray                 # [3] unit
    rolls_deg: list[int]           # per camera: 0, 90, 180 or 270
    method: str                    # cameras | cameras+planes | fallback-look-down | fallback-upright | fallback-z
    fallback: bool = False
    margin: float = float("inf")   # cost gap (per camera) to the best solution > 30 deg away
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        rolls = np.asarray(self.rolls_deg)
        return {"up": [float(v) for v in self.up], "method": self.method, "fallback": self.fallback,
                "margin": float(self.margin) if math.isfinite(self.margin) else None,
                "roll_counts": {str(r): int((rolls == r).sum()) for r in (0, 90, 180, 270)}, "notes": self.notes}


def _camera_cost(dirs: np.ndarray, a: np.ndarray, h: np.ndarray, cfg: UpConfig) -> tuple[np.ndarray, np.ndarray]:
    """Per-camera cost [M,C] of candidate ups ``dirs`` [M,3] with the best roll, and that roll [M,C]."""
    s = math.sin(math.radians(cfg.residual_deg))
    res = np.minimum((np.einsum("md,ckd->mck", dirs, h) / s) ** 2, 4.0)
    cos_p = np.clip(np.einsum("md,ckd->mck", dirs, a), -1, 1)
    pitch = np.degrees(np.arccos(cos_p)) / cfg.pitch_scale_deg
    cost = res + np.minimum(pitch ** 2, 1.5) + np.asarray(cfg.roll_prior)[None, None, :]
    k = np.argmin(cost, 2)
    return np.take_along_axis(cost, k[..., None], 2)[..., 0], k


def refine_up(a: np.ndarray, h: np.ndarray, prior_weight: float = 1e-3) -> np.ndarray:
    """Up [3] most orthogonal to the horizontal axes ``h`` [C,3], signed and weakly pulled
    towards the mean image-up axis of ``a`` [C,3] (closed form, smallest eigenvector)."""
    abar = a.mean(0)
    if np.linalg.norm(abar) < 1e-9:
        abar = a[0]
    ahat = unit(abar)
    M = h.T @ h / len(h) + prior_weight * (np.eye(3) - np.outer(ahat, ahat))
    up = np.linalg.eigh(M)[1][:, 0]
    return up if up @ ahat >= 0 else -up


def estimate_up(cameras: Sequence[Camera], points: np.ndarray | None = None,
                cfg: UpConfig | None = None) -> UpEstimate:
    """World up of a capture from its cameras (and optionally points [N,3]); never raises for geometry.

    See the module docstring for the cues and the fallback.
    """
    cfg = cfg or UpConfig()
    if len(cameras) == 0:
        msg = "estimate_up: no cameras; falling back to +z"
        log.warning(msg)
        return UpEstimate(Z_UP.copy(), [], "fallback-z", True, 0.0, [msg])
    a, h = roll_axes(cameras)
    C = len(cameras)
    centres = np.stack([c.center for c in cameras])
    pos, normals, weights = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    if points is not None and len(points) >= 50 and cfg.plane_weight > 0:
        pos, normals, weights = point_normals(points)
        keep = weights >= cfg.min_planarity
        pos, normals, weights = pos[keep], normals[keep], weights[keep]
        if len(normals) < 20:
            pos, normals, weights = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)

    def total(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cc, kk = _camera_cost(dirs, a, h, cfg)
        t = cc.mean(1)
        if len(normals):
            t = t + cfg.plane_weight * plane_cost(dirs, pos, normals, weights, centres)
        return t, kk

    def polish(u0: np.ndarray, k0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closed-form refinement for the roll assignment ``k0``; a 1-D search where the
        horizontal axes leave one direction free."""
        ak, hk = a[np.arange(C), k0], h[np.arange(C), k0]
        u = refine_up(ak, hk, cfg.prior_weight)
        ev, evec = np.linalg.eigh(hk.T @ hk / C)
        if ev[1] < cfg.degenerate_ratio * max(ev[2], 1e-12) and len(normals):
            # free within span(evec0, evec1): search the angle with the full cost
            th = np.radians(np.arange(0.0, 360.0, 0.5))
            fam = np.cos(th)[:, None] * evec[:, 0] + np.sin(th)[:, None] * evec[:, 1]
            t, _ = total(fam)
            u = fam[int(np.argmin(t))]
        t, k = total(u[None])
        return u, k[0]

    dirs = np.concatenate([fibonacci_sphere(2000), a.reshape(-1, 3)])
    t, k = total(dirs)
    order = np.argsort(t, kind="stable")
    solutions: list[tuple[float, np.ndarray, np.ndarray]] = []
    for i in order[:40]:  # polish the best few distinct candidates
        if any(unit(dirs[i]) @ s[1] > math.cos(math.radians(5)) for s in solutions):
            continue
        u, kk = polish(dirs[i], k[i])
        tt = float(total(u[None])[0][0])
        solutions.append((tt, u, kk))
        if len(solutions) >= 6:
            break
    solutions.sort(key=lambda s: s[0])
    best_t, best_u, best_k = solutions[0]
    others = [s[0] for s in solutions[1:] if angle_deg(s[1], best_u) > 30]
    margin = (min(others) - best_t) if others else float("inf")
    method = "cameras+planes" if len(normals) else "cameras"
    notes: list[str] = []
    if margin < cfg.min_margin:
        rival = next(s for s in solutions[1:] if angle_deg(s[1], best_u) > 30)
        if angle_deg(rival[1], best_u) > 150:  # a sign tie (all photos sideways): the cameras look down
            fwd = np.stack([c.forward for c in cameras])
            u, kk = (best_u, best_k) if float(np.median(fwd @ best_u)) <= 0 else (rival[1], rival[2])
            msg = ("estimate_up: undecidable sign (up and -up fit equally, photos sideways without a visible "
                   "ground); falling back to the sign for which the cameras look down")
            log.warning(msg)
            return UpEstimate(unit(u), [int(90 * k) for k in kk], "fallback-look-down", True, margin, [msg])
        u0 = refine_up(a[:, 0], h[:, 0], cfg.prior_weight)
        msg = (f"estimate_up: undecidable (two solutions {angle_deg(best_u, solutions[1][1]):.0f} deg apart score "
               f"within {margin:.3f}); falling back to upright photos (roll 0): up = the cameras' mean image-up axis")
        log.warning(msg)
        return UpEstimate(u0, [0] * C, "fallback-upright", True, margin, [msg])
    rolls = [int(90 * kk) for kk in best_k]
    n_rolled = sum(r != 0 for r in rolls)
    if n_rolled:
        notes.append(f"{n_rolled} of {C} cameras are rolled (photos stored sideways or upside down)")
        log.info("estimate_up: %s", notes[-1])
    return UpEstimate(unit(best_u), rolls, method, False, margin, notes)
