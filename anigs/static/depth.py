"""Depth supervision of the static fit from SfM tracks (:mod:`anigs.sfm.tracks`).

Few photos of a large scene (a street walk: 2-3 photos per facade at grazing angles) let the fit
memorise each training photo with splats at the wrong depth, which the held-out photos then see
smeared. The SfM points each training photo observes fix the depth where they are: the loss is the
mean ``|log(d_render / d_sfm)|`` (less a tolerance, ``static.depth_tolerance``: the SfM depths are not
exact either) over a photo's observed points where the render is opaque
(alpha > :data:`MIN_ALPHA`), ``d_render`` the rasterizer's expected depth (already divided by alpha)
at the observation's pixel, weighted by :func:`depth_weight` (decaying over the fit: the points
place the surfaces early, the photos refine them).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.static.evaluate import render_params

log = logging.getLogger("anigs.static.fit")

MIN_ALPHA = 0.5  # render alpha above which a pixel's expected depth is compared with the SfM depth


@dataclass(frozen=True)
class DepthTarget:
    """One training photo's SfM depths at the fit's photo size: flat pixel indices ``pixel`` [N]
    int64 (``y * width + x``) and ``log_depth`` [N] float32."""

    pixel: torch.Tensor
    log_depth: torch.Tensor

    @property
    def num(self) -> int:
        return int(self.pixel.numel())


def depth_targets(tracks: dict[str, np.ndarray], sizes: Sequence[tuple[int, int]], cameras: Sequence[Camera],
                  train_idx: Sequence[int], device: torch.device | str = "cpu") -> list[DepthTarget | None]:
    """The depth targets of the training photos ``train_idx`` (None for a photo without tracks).

    Args:
        tracks: image name -> rows (x, y, depth) [N,3] in the photo's pixels as captured
            (:func:`anigs.sfm.tracks.check_tracks` ran on them).
        sizes: each camera's (width, height) as captured (the tracks' pixels).
        cameras: the fit's cameras (maybe downscaled): the pixel grid of the targets.
        train_idx: indices into ``cameras`` of the training photos (held-out photos get no targets).
    Raises:
        ValueError naming images of ``tracks`` that no camera has, and rows outside their photo.
    """
    names = {c.name for c in cameras}
    unknown = sorted(set(tracks) - names)
    if unknown:
        raise ValueError(f"depth tracks: {len(unknown)} image(s) without a camera, e.g. {unknown[:3]} "
                         f"(cameras: {sorted(names)[:3]}...); are the tracks from this SfM?")
    out: list[DepthTarget | None] = []
    for i in train_idx:
        cam, (w0, h0) = cameras[i], sizes[i]
        rows = tracks.get(cam.name)
        if rows is None or not len(rows):
            out.append(None)
            continue
        outside = (rows[:, 0] < 0) | (rows[:, 0] > w0) | (rows[:, 1] < 0) | (rows[:, 1] > h0)
        if outside.any():
            raise ValueError(f"depth tracks: image {cam.name!r} has {int(outside.sum())} observation(s) outside its "
                             f"{w0}x{h0} pixels, e.g. {rows[outside][0, :2].tolist()}")
        x = np.clip(np.floor(rows[:, 0] * (cam.width / w0)), 0, cam.width - 1).astype(np.int64)
        y = np.clip(np.floor(rows[:, 1] * (cam.height / h0)), 0, cam.height - 1).astype(np.int64)
        out.append(DepthTarget(torch.from_numpy(y * cam.width + x).to(device),
                               torch.from_numpy(np.log(rows[:, 2].astype(np.float32))).to(device)))
    return out


def depth_loss(depth: torch.Tensor, alpha: torch.Tensor, target: DepthTarget, tolerance: float = 0.0) -> torch.Tensor:
    """Mean ``max(|log(depth / SfM depth)| - tolerance, 0)`` at ``target``'s pixels where ``alpha`` >
    :data:`MIN_ALPHA` (0-dim; 0 when none is). ``depth``, ``alpha``: the render's [H,W] (expected depth
    divided by alpha); ``tolerance``: what the SfM depths are trusted to (log ratio: 0.02 is 2%)."""
    d = depth.reshape(-1)[target.pixel]
    opaque = alpha.detach().reshape(-1)[target.pixel] > MIN_ALPHA
    err = (torch.log(d.clamp_min(1e-6)) - target.log_depth).abs()
    if tolerance > 0:
        err = (err - tolerance).clamp_min(0)
    return torch.where(opaque, err, torch.zeros_like(err)).sum() / opaque.sum().clamp_min(1)


def depth_weight(step: int, total: int, first: float, final: float) -> float:
    """The depth loss's weight at ``step`` of ``total``: ``first`` decaying log-linearly to ``final``
    (0 when ``first`` is 0; linearly to 0 when ``final`` is 0)."""
    if first <= 0:
        return 0.0
    t = min(max(step / max(total, 1), 0.0), 1.0)
    if final <= 0:
        return first * (1 - t)
    return math.exp((1 - t) * math.log(first) + t * math.log(final))


@torch.no_grad()
def depth_error(params: dict[str, torch.Tensor], cams: list[Camera], targets: list[DepthTarget | None], deg: int,
                 bg: torch.Tensor, backend: str) -> dict[str, object]:
    """The render's depth error at the photos' SfM points where it is opaque: the median over the
    photos of each photo's median ``|d_render / d_sfm - 1|``, and the points compared."""
    per_view, compared = [], 0
    for cam, t in zip(cams, targets):
        if t is None:
            continue
        _, alpha, meta = render_params(params, cam, deg, bg, backend)
        d, a = meta["depth"].reshape(-1)[t.pixel], alpha.reshape(-1)[t.pixel]
        ok = a > 0.5
        if ok.any():
            per_view.append(float((d[ok] / t.log_depth[ok].exp() - 1).abs().median()))
            compared += int(ok.sum())
    return {"median_rel": float(np.median(per_view)) if per_view else float("nan"), "views": len(per_view),
            "points": compared}


def depth_record(cfg, params: dict[str, torch.Tensor], train: tuple[list[Camera], list[DepthTarget | None]],
                 test: tuple[list[Camera], list[DepthTarget | None]], deg: int, bg: torch.Tensor) -> dict[str, object]:
    """``static/metrics.json`` ``depth``: the loss's settings (``cfg``: the fit's config) and the render's depth
    error at the SfM points of the training and the held-out photos ((cameras, targets) each); also logged."""
    rec = {"weight": cfg.depth_weight, "weight_final": cfg.depth_weight_final, "tolerance": cfg.depth_tolerance,
           "train_points": sum(t.num for t in train[1] if t is not None),
           "train": depth_error(params, *train, deg, bg, cfg.backend),
           "test": depth_error(params, *test, deg, bg, cfg.backend)}
    log.info("static fit: render depth at the SfM points off by a median %.1f%% (train), %.1f%% (held-out)",
             100 * rec["train"]["median_rel"], 100 * rec["test"]["median_rel"])
    return rec
