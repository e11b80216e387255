"""Containment of the dynamic set: a Gaussian may move only where the masks say things move.

Two checks, same measure: :func:`contain_dynamic` (masks stage, before any training) judges each
dynamic Gaussian's footprint where it sits; :func:`contain_motion` (update stage, after each
round's training) judges it at every frame of its learned motion, and first tries smaller
motions before it stops one.

The dynamic set lifted from the masks (or chosen by the effects stage) holds Gaussians whose
footprint reaches far beyond the dynamic region in some view: large or elongated halos at the
edge of a crown, blurry floaters near the camera, needle-like splats. Every pixel such a
Gaussian touches changes when it moves, so the sky, the walls and the lawn around the region
flicker. On the demo, before containment, these made 0.20 of the pixels outside the dilated mask
of the worst view change by more than 1/255 (0.05 over all views; by up to 50 levels).

:func:`contain_dynamic` keeps a dynamic Gaussian dynamic only when, in every view, the
blending weight it contributes to pixels *outside* that view's mask dilated by ``margin_px``
sums to at most ``max_outside_px`` (in pixel units: 1 = one fully covered pixel). The weight is
exact and occlusion-aware (:func:`anigs.render.visibility.blend_weights`: one forward-only pass of the
cpu rasterizer per view, one backward pass with the other backends), so a Gaussian hidden behind
a static wall in one view is judged by the views that see it. The others move to the static set:
they stay in the scene, bit for bit still.
The masks themselves are not changed (they stay the honest "what should move" region); only
the set of Gaussians allowed to move shrinks. The margin leaves room for the motion itself: a
kept Gaussian's footprint ends within ``margin_px`` of the mask, inside the 5 px band that the
still-pixel metric (:func:`anigs.metrics.motion.outside_mask_still`) forgives.

Measured (12 views each; before -> with both checks at their defaults):

- demo: dynamic Gaussians 3517 -> 2632 lifted (about 255 more stopped and 140 slowed per round);
  share of still pixels outside the masks dilated by 5 px 0.950 (worst view 0.80) -> 1.0 in every
  view; ground-truth motion: RMS amplitude ratio 0.85 -> 0.91, frequency W1 0.0165 -> 0.0163.
  What still moves moves less in image space (``dynamic_abs_diff`` 0.0041 -> 0.0023): the
  stopped Gaussians are mostly the blurry outer shell of the crowns, which reach into the sky.
  Both margins at 5 px: 0.99999, 0.0027, ratio 0.89, W1 0.0166.
- flower-llff (photos): 0.834 (worst 0.40) -> 1.0 in every view, ``dynamic_abs_diff`` 0.0275 ->
  0.0266 (232 of 24311 stopped at rest; per round about 150 stopped and 450 slowed).
"""
from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.pixels import dilate
from anigs.render.visibility import blend_weights, check_mask

log = logging.getLogger("anigs.masks.contain")


@dataclass
class ContainResult:
    """Outcome of :func:`contain_dynamic`."""

    dynamic: np.ndarray        # bool [N]: the contained dynamic set
    outside: np.ndarray        # float [N]: the largest weight (px) outside a view's dilated mask (0 for static)
    worst_view: np.ndarray     # int [N]: the view of that largest weight (-1 for static)

    def info(self, before: np.ndarray, names: Sequence[str], margin_px: int, max_outside_px: float) -> dict:
        frozen = before & ~self.dynamic
        per_view = {n: int((frozen & (self.worst_view == k)).sum()) for k, n in enumerate(names)}
        return {"margin_px": int(margin_px), "max_outside_px": float(max_outside_px),
                "dynamic_before": int(before.sum()), "dynamic_after": int(self.dynamic.sum()),
                "frozen": int(frozen.sum()), "frozen_by_view": per_view}


def dilate_mask(mask: np.ndarray, px: int) -> np.ndarray:
    """Binary dilation of a bool mask by ``px`` pixels (square structuring element, as the metric)."""
    return dilate(np.asarray(mask, bool), int(px))


def _reaching(g: Gaussians, cam: Camera, dist: np.ndarray) -> torch.Tensor:
    """Indices of the Gaussians whose rasterized footprint can reach a pixel where ``dist`` [H,W]
    (distance in pixels to the nearest pixel that counts; 0 on them) is 0. A conservative cull: the
    footprint radius bounds the rasterizer's (the ellipse where alpha >= 1/255: at most 3.33 sigma,
    plus its 0.3 px^2 low-pass) by 3.5 x the largest scale with the perspective stretch, plus 3 px;
    the others put no weight on those pixels, and leaving them out changes no weight there."""
    means = g.means.detach().cpu().double().numpy()
    pc = means @ cam.R.T + cam.t
    z = pc[:, 2]
    front = z > 0.01
    zs = np.where(front, z, 1.0)
    u = pc[:, 0] / zs * cam.K[0, 0] + cam.K[0, 2]
    v = pc[:, 1] / zs * cam.K[1, 1] + cam.K[1, 2]
    slope = np.sqrt(1.0 + (pc[:, 0] / zs) ** 2 + (pc[:, 1] / zs) ** 2)
    r = 3.5 * g.scales.detach().cpu().double().max(1).values.numpy() / zs * max(cam.K[0, 0], cam.K[1, 1]) * slope + 3.0
    H, W = dist.shape
    inside = front & (u >= 0) & (u < W) & (v >= 0) & (v < H)
    ui = np.clip(np.where(inside, u, 0), 0, W - 1).astype(np.int64)
    vi = np.clip(np.where(inside, v, 0), 0, H - 1).astype(np.int64)
    near_image = front & (u + r >= 0) & (u - r <= W) & (v + r >= 0) & (v - r <= H)
    reach = np.where(inside, dist[vi, ui] <= r, near_image)
    return torch.from_numpy(np.nonzero(reach)[0])


def _outside_weight(g: Gaussians, cam: Camera, outside: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Blending weight [N] of every Gaussian on the ``outside`` pixels, rasterizing only those that reach them."""
    w = np.zeros(g.num)
    idx = _reaching(g, cam, dist)
    if len(idx):
        w[idx.numpy()] = blend_weights(g.subset(idx), cam, outside)[1]
    return w


def _outside_region(mask: np.ndarray, cam: Camera, margin_px: int) -> tuple[np.ndarray, np.ndarray]:
    """(pixels outside the mask dilated by ``margin_px`` [H,W], their distance map for :func:`_reaching`)."""
    outside = ~dilate_mask(check_mask(mask, cam, "containment mask"), margin_px)
    dist = cv2.distanceTransform((~outside).astype(np.uint8), cv2.DIST_L2, 5)
    return outside, dist


def outside_weights(g: Gaussians, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                    margin_px: int = 3) -> np.ndarray:
    """Blending weight [V,N] (pixel units) of every Gaussian on the pixels outside each view's
    mask dilated by ``margin_px``."""
    if len(cameras) != len(masks):
        raise ValueError(f"containment: {len(cameras)} cameras but {len(masks)} masks")
    if margin_px < 0:
        raise ValueError(f"containment: margin_px must be >= 0, got {margin_px}")
    out = np.zeros((len(cameras), g.num))
    for k, (cam, mask) in enumerate(zip(cameras, masks)):
        outside, dist = _outside_region(mask, cam, margin_px)
        if outside.any():
            out[k] = _outside_weight(g, cam, outside, dist)
    return np.maximum(out, 0.0)


def contain_dynamic(g: Gaussians, dynamic: np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                    margin_px: int = 3, max_outside_px: float = 0.05) -> ContainResult:
    """The dynamic Gaussians whose footprint stays inside the dilated masks of every view (see the
    module docstring); ``dynamic`` [N] bool. Deterministic (exact rasterizer weights, fixed order)."""
    dynamic = np.asarray(dynamic, bool)
    if dynamic.shape != (g.num,):
        raise ValueError(f"containment: dynamic flags have shape {dynamic.shape}, the Gaussians number {g.num}")
    if not max_outside_px >= 0:
        raise ValueError(f"containment: max_outside_px must be >= 0, got {max_outside_px}")
    outside = np.zeros(g.num)
    worst = np.full(g.num, -1, np.int64)
    if dynamic.any() and len(cameras):
        w = outside_weights(g, cameras, masks, margin_px)
        outside = np.where(dynamic, w.max(0), 0.0)
        worst = np.where(dynamic, w.argmax(0), -1)
    keep = dynamic & (outside <= max_outside_px)
    log.info("containment: %d of %d dynamic Gaussians reach more than %.3g px of weight outside the masks "
             "dilated by %d px in some view: they stay still", int((dynamic & ~keep).sum()), int(dynamic.sum()),
             max_outside_px, margin_px)
    return ContainResult(keep, outside, worst)


def motion_outside_weights(canonical: Gaussians, deformation, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                           margin_px: int = 3, times: Sequence[float] | None = None,
                           views: Sequence[int] | None = None) -> np.ndarray:
    """Per view and dynamic Gaussian of ``deformation`` (a :class:`~anigs.animate.deform.DCTDeformation`
    over ``canonical``), [V,D]: the largest blending weight (px) the Gaussian puts outside the view's
    mask dilated by ``margin_px`` at any of the frame ``times`` (default: every integer frame).
    Only the ``views`` listed (default: all) are rendered; the other rows are 0."""
    if len(cameras) != len(masks):
        raise ValueError(f"containment: {len(cameras)} cameras but {len(masks)} masks")
    if margin_px < 0:
        raise ValueError(f"containment: margin_px must be >= 0, got {margin_px}")
    idx = deformation.dynamic_index.detach().cpu().numpy()
    best = np.zeros((len(cameras), len(idx)))
    views = range(len(cameras)) if views is None else sorted({int(k) for k in views})
    regions = {k: _outside_region(masks[k], cameras[k], margin_px) for k in views}
    regions = {k: r for k, r in regions.items() if r[0].any()}
    if not len(idx) or not regions:
        return best
    canonical = canonical.detach().to("cpu")
    deformation = deformation.to("cpu")
    for t in (range(deformation.num_frames) if times is None else times):
        with torch.no_grad():
            g = deformation(canonical, t)
        for k, (out, dist) in regions.items():
            best[k] = np.maximum(best[k], _outside_weight(g, cameras[k], out, dist)[idx])
    return best


def scaled_motion(deformation, factors: np.ndarray):
    """A copy of ``deformation`` with each dynamic Gaussian's coefficients (position and rotation)
    multiplied by ``factors`` [D]: its motion shrinks about its canonical position by that factor."""
    f = torch.as_tensor(np.asarray(factors), dtype=deformation.pos_coeffs.dtype)[:, None, None]
    state = deformation.state()
    state["pos_coeffs"] = state["pos_coeffs"] * f
    if state.get("rot_coeffs") is not None:
        state["rot_coeffs"] = state["rot_coeffs"] * f
    return type(deformation).from_state(state)


def contain_motion(canonical: Gaussians, deformation, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                   margin_px: int = 3, max_outside_px: float = 0.01, times: Sequence[float] | None = None,
                   steps: Sequence[float] = (0.5, 0.25)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The trained motion's containment. Motion can carry a Gaussian that sits inside the masks out
    of them (a frond swaying across the mask border by more than the metric's band). A dynamic
    Gaussian of ``deformation`` whose footprint, in some frame and view, puts more than
    ``max_outside_px`` of weight outside the view's mask dilated by ``margin_px`` has its motion
    scaled down by the next factor of ``steps`` and is checked again (all frames, in the views it
    left the masks in, the others as they stand); one that still leaks at the last factor stays
    still (factor 0).

    Returns (factor [D] over the rows of ``deformation.dynamic_index``: 1 = untouched, 0 = frozen;
    the weight outside at the factor it was last checked at [D]; the view of that weight [D])."""
    if not max_outside_px >= 0:
        raise ValueError(f"containment: max_outside_px must be >= 0, got {max_outside_px}")
    levels = [1.0] + [float(x) for x in steps]
    if any(not 0 < b < a for a, b in itertools.pairwise(levels)):
        raise ValueError(f"containment: steps must decrease within (0, 1), got {list(steps)}")
    D = deformation.num_dynamic
    level = np.zeros(D, np.int64)  # index into levels
    outside = np.zeros(D)
    worst = np.full(D, -1, np.int64)
    check = np.ones(D, bool)
    views = None  # all views first; then only those some Gaussian still left the masks in
    for _ in range(len(levels)):
        factors = np.array(levels)[level]
        w = motion_outside_weights(canonical, scaled_motion(deformation, factors) if (factors < 1).any()
                                   else deformation, cameras, masks, margin_px, times, views)  # [V,D]
        outside[check], worst[check] = w.max(0)[check], np.where(w.max(0) > 0, w.argmax(0), -1)[check]
        leaks = check[None] & (w > max_outside_px)
        fail = leaks.any(0)
        if not fail.any():
            break
        level[fail] += 1
        check = fail & (level < len(levels))
        views = np.nonzero((leaks & check[None]).any(1))[0]
        if not check.any():
            break
    factor = np.array(levels + [0.0])[level]
    log.info("containment of the motion: of %d dynamic Gaussians, %d keep their motion, %d move less (factors %s) "
             "and %d stay still (more than %.3g px of weight outside the masks dilated by %d px in some frame and "
             "view)", D, int((factor == 1).sum()), int(((factor > 0) & (factor < 1)).sum()), levels[1:],
             int((factor == 0).sum()), max_outside_px, margin_px)
    return factor, outside, worst
