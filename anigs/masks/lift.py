"""Per-Gaussian visibility and lifting 2D masks to 3D Gaussians.

Two visibility tests, both for a Gaussian set seen from one :class:`~anigs.cameras.Camera`:

``depth``
    Project each Gaussian centre; it is visible when it lies in the image, in front of the
    near plane, and not behind the rendered (expected) depth at its pixel by more than a
    tolerance (``rel_tol * depth + scale_tol * max_scale``).
``weight``
    The exact blending weight each Gaussian contributes to the image, summed over pixels
    (``sum_p w_i(p)``), and summed over a mask (``sum_p mask(p) w_i(p)``). With the cpu
    rasterizer one forward-only kernel pass accumulates both while compositing; otherwise
    one backward pass of the rasterizer with zero colours gives them
    (``d(sum_p rgb_0(p)) / d colour_i0 = sum_p w_i(p)``, a second channel weighted by the
    mask). Visible = total weight >= ``min_weight`` (in pixel units).

:func:`lift_masks` votes, per Gaussian, among the views where it is visible: dynamic when
the fraction of positive votes is >= ``vote_threshold`` and it is visible in >= ``min_views``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.configs import from_dict
from anigs.gaussians import Gaussians
from anigs.render import rasterize

VISIBILITY_MODES = ("depth", "weight", "frustum")


@dataclass
class VisibilityConfig:
    """Visibility test parameters (see module docstring)."""

    mode: str = "depth"
    rel_tol: float = 0.03
    scale_tol: float = 2.0
    min_alpha: float = 0.5
    min_weight: float = 0.05
    near: float = 0.01

    def __post_init__(self) -> None:
        if self.mode not in VISIBILITY_MODES:
            raise ValueError(f"visibility mode must be one of {VISIBILITY_MODES}, got {self.mode!r}")


@dataclass
class LiftConfig:
    """Parameters of the 2D-to-3D mask lifting (config key ``lift``)."""

    min_views: int = 1            # min views in which a Gaussian is visible to be dynamic
    vote_threshold: float = 0.5   # min fraction of those views whose mask covers it
    visibility: str = "weight"    # weight | depth | frustum
    rel_tol: float = 0.03         # depth test: relative tolerance
    scale_tol: float = 2.0        # depth test: tolerance in Gaussian max-scales
    min_alpha: float = 0.5        # depth test: pixels below this alpha occlude nothing
    min_weight: float = 0.05      # weight test: min summed blending weight (pixels)
    propagate_k: int = 8          # Gaussians seen in < min_views views take the majority of their
                                  # k nearest decided neighbours (0 = they stay static)
    weighted_votes: bool = True   # weight visibility: votes weighted by blending weight
    ground_cut: float = 0.5       # with a ground plane: static below this fraction of its min_height

    def __post_init__(self) -> None:
        if self.ground_cut < 0:
            raise ValueError(f"lift.ground_cut must be >= 0, got {self.ground_cut}")
        if self.propagate_k < 0:
            raise ValueError(f"lift.propagate_k must be >= 0, got {self.propagate_k}")
        if self.min_views < 1:
            raise ValueError(f"lift.min_views must be >= 1, got {self.min_views}")
        if not 0.0 < self.vote_threshold <= 1.0:
            raise ValueError(f"lift.vote_threshold must be in (0, 1], got {self.vote_threshold}")
        self.visibility_config()

    @staticmethod
    def from_dict(d: dict | None) -> "LiftConfig":

        return from_dict(LiftConfig, d, "lift config", ValueError)

    def visibility_config(self) -> "VisibilityConfig":
        return VisibilityConfig(mode=self.visibility, rel_tol=self.rel_tol, scale_tol=self.scale_tol,
                                min_alpha=self.min_alpha, min_weight=self.min_weight)


def _as_gaussians(g: Gaussians | torch.Tensor | np.ndarray) -> tuple[np.ndarray, Gaussians | None]:
    if isinstance(g, Gaussians):
        return g.means.detach().cpu().double().numpy(), g
    means = g.detach().cpu().double().numpy() if torch.is_tensor(g) else np.asarray(g, dtype=np.float64)
    if means.ndim != 2 or means.shape[1] != 3:
        raise ValueError(f"means must be [N,3], got {means.shape}")
    return means, None


def frustum_subset(g: Gaussians, cam: Camera, near: float = 0.01, sigmas: float = 3.0) -> torch.Tensor:
    """Indices [M] of the Gaussians whose ``sigmas``-extent can reach the image of ``cam``.

    A cheap conservative pre-cull (centre in front of the near plane, projected centre
    within the image grown by the projected radius ``sigmas * max_scale * f / z``) so
    renders of a scene from many cameras only rasterize what each camera can see.
    """
    means = g.means.detach().cpu().double().numpy()
    rad = g.scales.detach().cpu().double().max(1).values.numpy() * sigmas
    pc = means @ cam.R.T + cam.t
    z = pc[:, 2]
    front = z > near
    zs = np.where(front, z, 1.0)
    u = pc[:, 0] / zs * cam.K[0, 0] + cam.K[0, 2]
    v = pc[:, 1] / zs * cam.K[1, 1] + cam.K[1, 2]
    # projected radius, with the off-axis stretch of the perspective Jacobian, + 2 px of dilation
    slope = np.sqrt(1.0 + (pc[:, 0] / zs) ** 2 + (pc[:, 1] / zs) ** 2)
    r = rad / zs * max(cam.K[0, 0], cam.K[1, 1]) * slope + 2.0
    keep = front & (u + r >= 0) & (u - r <= cam.width) & (v + r >= 0) & (v - r <= cam.height)
    return torch.from_numpy(np.nonzero(keep)[0])


def render_inputs(g: Gaussians, idx: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """(means, quats, scales, opacities) of the Gaussians ``idx``, detached float32 CPU tensors."""
    return (g.means.detach().float().cpu()[idx], g.quats.detach().float().cpu()[idx],
            g.scales.detach().float().cpu()[idx], g.opacities.detach().float().cpu()[idx])


def render_depth(g: Gaussians, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Expected depth [H,W] and alpha [H,W] of ``g`` seen from ``cam`` (numpy float32)."""
    idx = frustum_subset(g, cam)
    with torch.no_grad():
        colors = torch.zeros(len(idx), 3)
        _, alpha, meta = rasterize(*render_inputs(g, idx), colors, cam.torch_viewmat(), cam.torch_K(),
                                   cam.width, cam.height)
    return meta["depth"].numpy(), alpha.numpy()


def project_to_pixels(means: np.ndarray, cam: Camera,
                      near: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixel indices of Gaussian centres.

    Returns (inside [N] bool, px [N] int, py [N] int, z [N]); px/py are 0 where not inside.
    """
    uv, z = cam.project(means)
    with np.errstate(invalid="ignore"):
        inside = (z > near) & np.isfinite(uv).all(1)
        u = np.where(inside, uv[:, 0], -1.0)
        v = np.where(inside, uv[:, 1], -1.0)
        inside &= (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
    px = np.where(inside, np.floor(u), 0).astype(np.int64)
    py = np.where(inside, np.floor(v), 0).astype(np.int64)
    return inside, px, py, z


def visible_depth(means: np.ndarray, cam: Camera, depth: np.ndarray | None, alpha: np.ndarray | None,
                  max_scale: np.ndarray | float = 0.0, cfg: VisibilityConfig | None = None) -> np.ndarray:
    """Depth-test visibility bool [N] (frustum test only when ``depth`` is None)."""
    cfg = cfg or VisibilityConfig()
    inside, px, py, z = project_to_pixels(means, cam, cfg.near)
    if depth is None:
        return inside
    if depth.shape != (cam.height, cam.width):
        raise ValueError(f"depth map is {depth.shape[1]}x{depth.shape[0]}, "
                         f"camera {cam.name!r} is {cam.width}x{cam.height}")
    d = depth[py, px]
    a = alpha[py, px] if alpha is not None else np.ones_like(d)
    tol = cfg.rel_tol * d + cfg.scale_tol * np.asarray(max_scale)
    occluded = (a >= cfg.min_alpha) & (z > d + tol)
    return inside & ~occluded


def _blend_backend() -> str:
    """The rasterizer backend that renders the CPU tensors of :func:`render_inputs` (``auto``)."""
    from anigs.render.rasterize import select_backend

    return select_backend("auto", torch.device("cpu"))


def blend_weights(g: Gaussians, cam: Camera, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-Gaussian blending weight summed over pixels: (total [N], inside ``mask`` [N]).

    Exact (see module docstring). With the cpu rasterizer one forward-only kernel pass
    (:func:`anigs.render.cpu_backend.composite_weights_cpu`) sums them during compositing;
    with the other backends one backward pass gives them (:func:`blend_weights_backward`).
    """
    backend = _blend_backend()
    if backend != "cpu":
        return blend_weights_backward(g, cam, mask, backend)
    from anigs.render.cpu_backend import composite_weights_cpu

    idx = frustum_subset(g, cam)
    total = np.zeros(g.num)
    inside = np.zeros(g.num)
    if len(idx) == 0:
        return total, inside
    ones = torch.ones(cam.height, cam.width, 1)
    factors = ones if mask is None else torch.cat(
        [ones, torch.from_numpy(np.asarray(mask, dtype=np.float32)).reshape(cam.height, cam.width, 1)], 2)
    w = composite_weights_cpu(*render_inputs(g, idx), cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height,
                              factors).numpy()
    total[idx.numpy()] = w[:, 0]
    if mask is not None:
        inside[idx.numpy()] = w[:, 1]
    return total, inside


def blend_weights_backward(g: Gaussians, cam: Camera, mask: np.ndarray | None = None,
                           backend: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """:func:`blend_weights` via one backward pass of the rasterizer ``backend`` with zero
    colours (``d(sum_p rgb_0(p)) / d colour_i0``; channel 1 weighted by the mask); the path of
    the torch and gsplat backends, and the reference of the forward-only one."""
    idx = frustum_subset(g, cam)
    total = np.zeros(g.num)
    inside = np.zeros(g.num)
    if len(idx) == 0:
        return total, inside
    colors = torch.zeros(len(idx), 3, requires_grad=True)
    rgb, _, _ = rasterize(*render_inputs(g, idx), colors, cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height,
                          backend=backend)
    gout = torch.zeros_like(rgb)
    gout[..., 0] = 1.0
    if mask is not None:
        gout[..., 1] = torch.from_numpy(np.asarray(mask, dtype=np.float32))
    rgb.backward(gout)
    if colors.grad is not None:
        total[idx.numpy()] = colors.grad[:, 0].double().numpy()
        inside[idx.numpy()] = colors.grad[:, 1].double().numpy()
    return total, inside


def visibility(g: Gaussians | torch.Tensor | np.ndarray, cam: Camera, cfg: VisibilityConfig | None = None,
               depth: np.ndarray | None = None, alpha: np.ndarray | None = None) -> np.ndarray:
    """Visible Gaussians bool [N] of ``g`` from ``cam`` with the configured test."""
    cfg = cfg or VisibilityConfig()
    means, gs = _as_gaussians(g)
    if cfg.mode == "frustum":
        return visible_depth(means, cam, None, None, cfg=cfg)
    if gs is None and not (cfg.mode == "depth" and depth is not None):
        raise ValueError(f"visibility mode {cfg.mode!r} needs the full Gaussians (or a depth map), got only means")
    if cfg.mode == "weight":
        total, _ = blend_weights(gs, cam)
        return total >= cfg.min_weight
    if depth is None:
        depth, alpha = render_depth(gs, cam)
    max_scale = gs.scales.detach().max(1).values.double().numpy() if gs is not None else 0.0
    return visible_depth(means, cam, depth, alpha, max_scale, cfg)


def check_mask(mask: np.ndarray, cam: Camera, what: str = "mask") -> np.ndarray:
    """Validate a 2D mask against a camera's size; return it as bool [H,W]."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"{what} for camera {cam.name!r} must be 2D [H,W], got shape {mask.shape}")
    if mask.shape != (cam.height, cam.width):
        raise ValueError(f"{what} for camera {cam.name!r} is {mask.shape[1]}x{mask.shape[0]} (WxH) "
                         f"but the camera is {cam.width}x{cam.height}")
    return mask.astype(bool)


def lift_votes(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
               cfg: VisibilityConfig | None = None, depths: Sequence[np.ndarray] | None = None,
               weighted: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Votes per Gaussian over the views: (positive [N], total [N], views seen [N int]).

    Per view a Gaussian that is visible votes 1 (positive when its pixel is in the mask). With
    ``weighted`` (``weight`` visibility only) it votes its blending weight, positive in
    proportion to the weight that falls inside the mask.
    """
    cfg = cfg or VisibilityConfig()
    if len(cameras) != len(masks):
        raise ValueError(f"lift: {len(cameras)} cameras but {len(masks)} masks")
    if depths is not None and len(depths) != len(cameras):
        raise ValueError(f"lift: {len(cameras)} cameras but {len(depths)} depth maps")
    means, gs = _as_gaussians(g)
    pos = np.zeros(len(means))
    tot = np.zeros(len(means))
    nvis = np.zeros(len(means), dtype=np.int64)
    for i, (cam, mask) in enumerate(zip(cameras, masks)):
        mask = check_mask(mask, cam)
        if cfg.mode == "weight":
            if gs is None:
                raise ValueError("lift: visibility 'weight' needs the full Gaussians, got only means")
            total, inside = blend_weights(gs, cam, mask)
            seen = total >= cfg.min_weight
            if weighted:
                pos += np.where(seen, inside, 0.0)
                tot += np.where(seen, total, 0.0)
            else:
                pos += seen & (inside >= 0.5 * np.maximum(total, 1e-12))
                tot += seen
        else:
            depth = None if depths is None else np.asarray(depths[i])
            seen = visibility(gs if gs is not None else means, cam, cfg, depth=depth)
            _, px, py, _ = project_to_pixels(means, cam, cfg.near)
            pos += seen & mask[py, px]
            tot += seen
        nvis += seen
    return pos, tot, nvis


def propagate_labels(means: np.ndarray, decided: np.ndarray, value: np.ndarray, k: int) -> np.ndarray:
    """Fill undecided entries of bool ``value`` [N] by majority over the ``k`` nearest decided Gaussians."""
    out = value.copy()
    und = ~decided
    if k <= 0 or not und.any() or not decided.any():
        return out
    from scipy.spatial import cKDTree

    k = min(k, int(decided.sum()))
    _, idx = cKDTree(means[decided]).query(means[und], k=k)
    idx = np.asarray(idx).reshape(int(und.sum()), k)
    out[und] = value[decided][idx].mean(1) > 0.5
    return out


def precision_recall(pred: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Precision and recall of a lifted dynamic set ``pred`` [N] bool against ``truth`` [N] bool
    (0 when the denominator is empty)."""
    tp = int((pred & truth).sum())
    return {"precision": tp / max(int(pred.sum()), 1), "recall": tp / max(int(truth.sum()), 1)}


def lift_masks_report(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                      cfg: LiftConfig | None = None, depths: Sequence[np.ndarray] | None = None,
                      ground=None) -> tuple[np.ndarray, dict]:
    """:func:`lift_masks` with a :class:`LiftConfig`; also returns counts (visible, voted, propagated).

    ``ground`` (a :class:`anigs.masks.vegetation.GroundPlane`): Gaussians whose centre lies
    below ``cfg.ground_cut * ground.min_height`` above it are static (the 3D twin of the
    2D ground cue: a lawn does not move). The cut stays at the fixed margin, not at the
    measured ground layer (``ground.layer``) that the vegetation masks use: grass tufts,
    flower beds and bush bottoms that good masks do mark live in that layer (on the demo,
    cutting there took 0.1 of recall from the lifted ground-truth label masks).
    """
    cfg = cfg or LiftConfig()
    means, _ = _as_gaussians(g)
    pos, tot, nvis = lift_votes(g, cameras, masks, cfg.visibility_config(), depths, weighted=cfg.weighted_votes)
    decided = nvis >= cfg.min_views
    frac = np.where(tot > 0, pos / np.maximum(tot, 1e-12), 0.0)
    dyn = decided & (frac >= cfg.vote_threshold)
    out = propagate_labels(means, decided, dyn, cfg.propagate_k)
    low = np.zeros(len(means), bool)
    if ground is not None and cfg.ground_cut > 0:
        low = means @ np.asarray(ground.normal, float) - ground.offset < cfg.ground_cut * ground.min_height
        out &= ~low
    info = {"num_gaussians": int(len(means)), "num_views": len(cameras), "decided": int(decided.sum()),
            "undecided": int((~decided).sum()), "dynamic_voted": int(dyn.sum()),
            "dynamic_propagated": int((out & ~decided).sum()), "below_ground_cut": int(low.sum()),
            "dynamic": int(out.sum()), "visibility": cfg.visibility, "weighted_votes": cfg.weighted_votes}
    return out, info


def lift_masks(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
               min_views: int = 1, vote_threshold: float = 0.5, visibility: str = "depth",
               depths: Sequence[np.ndarray] | None = None, propagate_k: int = 0,
               cfg: LiftConfig | None = None) -> np.ndarray:
    """Lift 2D masks (bool [H,W] per camera) to a dynamic flag per Gaussian, bool [N].

    ``g`` is a :class:`Gaussians` (needed for the ``depth`` test unless ``depths`` are given,
    and for ``weight``) or means [N,3] (``frustum`` visibility, or ``depth`` with ``depths``).
    A Gaussian is dynamic when visible in >= ``min_views`` views and the fraction of those
    views whose mask covers it is >= ``vote_threshold``. With ``propagate_k`` > 0 the
    Gaussians seen in fewer views take the majority of their k nearest decided neighbours.
    ``cfg`` (a :class:`LiftConfig`) overrides the keyword parameters.
    """
    if cfg is None:
        cfg = LiftConfig(min_views=min_views, vote_threshold=vote_threshold, visibility=visibility,
                         propagate_k=propagate_k)
    return lift_masks_report(g, cameras, masks, cfg, depths)[0]
