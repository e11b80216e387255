"""Per-Gaussian visibility: which Gaussians of a set a camera sees, and how much of each.

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

``frustum`` only keeps the centres that project into the image. The 2D-to-3D mask lifting
(:mod:`anigs.masks.lift`) votes with these tests.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render.cpu_backend import composite_weights_cpu
from anigs.render.rasterize import rasterize, select_backend

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


def as_means(g: Gaussians | torch.Tensor | np.ndarray) -> tuple[np.ndarray, Gaussians | None]:
    """(centres [N,3] float64, the Gaussians or None) of Gaussians, or of their centres [N,3]."""
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
    return select_backend("auto", torch.device("cpu"))


def _mask_channels(mask: np.ndarray | None, cam: Camera, n: int) -> tuple[torch.Tensor | None, np.ndarray]:
    """(``mask`` [H,W] or [H,W,K] (K <= 2) as float32 [H,W,K] or None, the zero inside weights: [n] for
    no mask or one [H,W] mask, else [n,K])."""
    if mask is None:
        return None, np.zeros(n)
    m = torch.from_numpy(np.asarray(mask, dtype=np.float32))
    m = m.reshape(cam.height, cam.width, -1)
    if m.shape[2] > 2:
        raise ValueError(f"blend_weights: at most 2 masks per pass, got {m.shape[2]}")
    return m, np.zeros(n) if np.ndim(mask) == 2 else np.zeros((n, m.shape[2]))


def blend_weights(g: Gaussians, cam: Camera, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-Gaussian blending weight summed over pixels: (total [N], inside ``mask`` [N]); ``mask``
    [H,W,K] (K <= 2 masks in the one pass) gives inside [N,K].

    Exact (see module docstring). With the cpu rasterizer one forward-only kernel pass
    (:func:`anigs.render.cpu_backend.composite_weights_cpu`) sums them during compositing;
    with the other backends one backward pass gives them (:func:`blend_weights_backward`).
    """
    backend = _blend_backend()
    if backend != "cpu":
        return blend_weights_backward(g, cam, mask, backend)
    masks, inside = _mask_channels(mask, cam, g.num)
    idx = frustum_subset(g, cam)
    total = np.zeros(g.num)
    if len(idx) == 0:
        return total, inside
    ones = torch.ones(cam.height, cam.width, 1)
    factors = ones if masks is None else torch.cat([ones, masks], 2)
    w = composite_weights_cpu(*render_inputs(g, idx), cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height,
                              factors).numpy()
    total[idx.numpy()] = w[:, 0]
    if masks is not None:
        inside[idx.numpy()] = w[:, 1] if inside.ndim == 1 else w[:, 1:]
    return total, inside


def blend_weights_backward(g: Gaussians, cam: Camera, mask: np.ndarray | None = None,
                           backend: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """:func:`blend_weights` via one backward pass of the rasterizer ``backend`` with zero
    colours (``d(sum_p rgb_0(p)) / d colour_i0``; channels 1 and 2 weighted by the masks); the path of
    the torch and gsplat backends, and the reference of the forward-only one."""
    masks, inside = _mask_channels(mask, cam, g.num)
    idx = frustum_subset(g, cam)
    total = np.zeros(g.num)
    if len(idx) == 0:
        return total, inside
    colors = torch.zeros(len(idx), 3, requires_grad=True)
    rgb, _, _ = rasterize(*render_inputs(g, idx), colors, cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height,
                          backend=backend)
    gout = torch.zeros_like(rgb)
    gout[..., 0] = 1.0
    if masks is not None:
        gout[..., 1:1 + masks.shape[2]] = masks
    rgb.backward(gout)
    if colors.grad is not None:
        total[idx.numpy()] = colors.grad[:, 0].double().numpy()
        k = 1 if masks is None else masks.shape[2]
        grad = colors.grad[:, 1:1 + k].double().numpy()
        inside[idx.numpy()] = grad[:, 0] if inside.ndim == 1 else grad
    return total, inside


def visibility(g: Gaussians | torch.Tensor | np.ndarray, cam: Camera, cfg: VisibilityConfig | None = None,
               depth: np.ndarray | None = None, alpha: np.ndarray | None = None) -> np.ndarray:
    """Visible Gaussians bool [N] of ``g`` from ``cam`` with the configured test."""
    cfg = cfg or VisibilityConfig()
    means, gs = as_means(g)
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
