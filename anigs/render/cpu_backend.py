"""Fast CPU rasterizer: compiled C++ kernel (``csrc/``) with hand-written backward.

Same semantics as the torch reference path of :func:`anigs.render.rasterize` (projection in
``projection.py``, colours in ``sh.py``, compositing in ``torch_backend.py``); float32 only.
Two autograd Functions, each one or a few kernel calls with no per-splat torch ops:

* ``_Preprocess``: per-Gaussian projection + colour (raw or SH degree 0-3) + input validation;
  outputs ``means2d`` (kept in the graph, so ``meta["means2d"].retain_grad()`` works),
  conics and feats (r, g, b, depth) for all N Gaussians.
* ``_Composite``: depth sort, tile binning, compositing and the image tail (background,
  alpha, expected depth); its backward returns per-Gaussian gradients directly.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from anigs.render import kernel as render_kernel
from anigs.render.checks import validate, check_inputs
from anigs.render.projection import EPS_2D

def _ptr(t: torch.Tensor | None) -> int | None:
    return None if t is None else t.data_ptr()


def _threads() -> int:
    return max(1, torch.get_num_threads())


def _f32(t: torch.Tensor) -> torch.Tensor:
    """Detached float32 contiguous view (no copy when it already is one)."""
    t = t.detach()
    if t.dtype != torch.float32:
        t = t.float()
    return t if t.is_contiguous() else t.contiguous()


def _grad_in(t: torch.Tensor | None) -> torch.Tensor | None:
    if t is None:
        return None
    if t.dtype != torch.float32:
        t = t.float()
    return t if t.is_contiguous() else t.contiguous()


def _image_grad(t: torch.Tensor | None) -> torch.Tensor | None:
    """Upstream image grad as float32, any strides (the kernel takes them: expanded grads
    such as those of ``rgb.sum()`` are read in place instead of being materialized)."""
    if t is None:
        return None
    return t if t.dtype == torch.float32 else t.float()


def _strides(t: torch.Tensor | None, n: int) -> list[int]:
    return [0] * n if t is None else list(t.stride())


def camera_params(viewmat: torch.Tensor, K: torch.Tensor, near: float, far: float, eps2d: float = EPS_2D,
                  on_invalid=None) -> torch.Tensor:
    """Kernel camera block [R(9), t(3), fx, fy, cx, cy, near, far, eps2d] (float32)."""
    v = viewmat.detach().cpu().flatten().tolist()  # python floats: exact for float32/64
    k = K.detach().cpu().flatten().tolist()
    if on_invalid is not None and not math.isfinite(sum(v) + sum(k)):  # any NaN/Inf (or beyond float32)
        on_invalid(0)
    vals = [*v[0:3], *v[4:7], *v[8:11], v[3], v[7], v[11], k[0], k[4], k[2], k[5],
            float(near), min(float(far), 3e38), float(eps2d)]
    return torch.tensor(vals, dtype=torch.float32)


class _Preprocess(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, quats, scales, opacities, colors, cam, sh_degree: int, width: int, height: int,
                on_invalid):
        lib = render_kernel.load()
        ctx.set_materialize_grads(False)  # unused outputs: None, not zero-filled tensors
        n = means.shape[0]
        ctx.dtypes = (means.dtype, quats.dtype, scales.dtype, colors.dtype)
        ctx.colors_shape = colors.shape
        m, q, s, o, c = (_f32(t) for t in (means, quats, scales, opacities, colors))
        k = 1 if sh_degree < 0 else c.shape[1]
        means2d, conics, feats = torch.empty(n, 2), torch.empty(n, 3), torch.empty(n, 4)
        rects = torch.empty(n, 4, dtype=torch.int32)
        radii = torch.empty(n, dtype=torch.int32)
        valid = torch.empty(n, dtype=torch.uint8)
        flags = lib.anigs_preprocess(n, _ptr(cam), width, height, _ptr(m), _ptr(q), _ptr(s), _ptr(o), _ptr(c),
                                     k, sh_degree, _ptr(means2d), _ptr(conics), _ptr(feats), _ptr(rects),
                                     _ptr(radii), _ptr(valid), int(on_invalid is not None), _threads())
        if flags and on_invalid is not None:
            on_invalid(flags)
        ctx.save_for_backward(m, q, s, c, valid, cam)
        ctx.args = (sh_degree, k, width, height)
        ctx.mark_non_differentiable(rects, radii, valid)
        return means2d, conics, feats, rects, radii, valid

    @staticmethod
    def backward(ctx, g_m2d, g_con, g_feat, _r, _rad, _v):
        lib = render_kernel.load()
        m, q, s, c, valid, cam = ctx.saved_tensors
        sh_degree, k, width, height = ctx.args
        n = m.shape[0]
        gm, gq, gs = torch.empty(n, 3), torch.empty(n, 4), torch.empty(n, 3)
        gc = torch.empty(ctx.colors_shape)
        g_m2d, g_con, g_feat = _grad_in(g_m2d), _grad_in(g_con), _grad_in(g_feat)
        lib.anigs_preprocess_backward(n, _ptr(cam), width, height, _ptr(m), _ptr(q), _ptr(s), _ptr(c), k, sh_degree,
                                      _ptr(valid), _ptr(g_m2d), _ptr(g_con), _ptr(g_feat),
                                      _ptr(gm), _ptr(gq), _ptr(gs), _ptr(gc), _threads())
        dm, dq, ds, dc = ctx.dtypes
        return gm.to(dm), gq.to(dq), gs.to(ds), None, gc.to(dc), None, None, None, None, None


class _Composite(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, feats, opacities, background, valid, rects, width: int, height: int,
                info: dict):
        lib = render_kernel.load()
        # an unused output (often depth) then has no gradient tensor: the kernel skips that
        # channel instead of reading materialized zeros
        ctx.set_materialize_grads(False)
        nt = _threads()
        n = means2d.shape[0]
        ctx.opac_dtype, ctx.bg_dtype = opacities.dtype, background.dtype
        o = _f32(opacities)
        bg = _f32(background)
        order = torch.empty(max(n, 1), dtype=torch.int32)
        gstart = torch.empty(n + 1, dtype=torch.int32)
        npairs = render_kernel.ctypes.c_longlong(0)
        M = lib.anigs_sort_count(n, _ptr(feats), _ptr(valid), _ptr(rects), _ptr(means2d), _ptr(conics), _ptr(o),
                                 width, height, _ptr(order), _ptr(gstart), render_kernel.ctypes.byref(npairs), nt)
        npairs = npairs.value
        if npairs >= 2**31:
            raise ValueError(f"rasterize: {npairs} (tile, Gaussian) pairs exceed the cpu backend's int32 limit")
        ntiles = ((width + 15) // 16) * ((height + 15) // 16)
        recs = torch.empty(max(M, 1), 16)
        tile_offsets = torch.empty(ntiles + 1, dtype=torch.int32)
        tile_splats = torch.empty(max(npairs, 1), dtype=torch.int32)
        tile_rects = torch.empty(max(npairs, 1), dtype=torch.int32)
        rgb, alpha, depth = torch.empty(height, width, 3), torch.empty(height, width), torch.empty(height, width)
        pair_slots = T = accd = last = None
        if any(ctx.needs_input_grad):  # buffers only the backward reads
            pair_slots = torch.empty(max(npairs, 1), dtype=torch.int32)
            T, accd = torch.empty(height, width), torch.empty(height, width)
            last = torch.empty(height, width, dtype=torch.int32)
        lib.anigs_composite_forward(M, width, height, _ptr(order), _ptr(gstart), _ptr(means2d), _ptr(conics),
                                    _ptr(feats), _ptr(o), _ptr(rects), _ptr(bg), _ptr(recs), _ptr(tile_offsets),
                                    _ptr(tile_splats), _ptr(tile_rects), _ptr(pair_slots), _ptr(rgb), _ptr(alpha), _ptr(depth),
                                    _ptr(T), _ptr(accd), _ptr(last), nt)
        # kernel-owned intermediates (neither inputs nor outputs): kept on ctx directly
        ctx.state = (n, M, width, height, order, gstart, valid, recs, tile_offsets, tile_splats, tile_rects,
                     pair_slots, bg, T, accd, last)
        info["num_visible"] = M
        return rgb, alpha, depth

    @staticmethod
    def backward(ctx, g_rgb, g_alpha, g_depth):
        lib = render_kernel.load()
        (n, M, width, height, order, gstart, valid, recs, tile_offsets, tile_splats, tile_rects, pair_slots, bg,
         T, accd, last) = ctx.state
        g_m2d, g_con, g_feat, g_o = torch.empty(n, 2), torch.empty(n, 3), torch.empty(n, 4), torch.empty(n)
        g_rgb, g_alpha, g_depth = _image_grad(g_rgb), _image_grad(g_alpha), _image_grad(g_depth)
        gstrides = (render_kernel.ctypes.c_longlong * 7)(*_strides(g_rgb, 3), *_strides(g_alpha, 2), *_strides(g_depth, 2))
        lib.anigs_composite_backward(n, M, width, height, _ptr(order), _ptr(gstart), _ptr(valid), _ptr(recs),
                                     _ptr(tile_offsets), _ptr(tile_splats), _ptr(tile_rects), _ptr(pair_slots),
                                     _ptr(bg), _ptr(T), _ptr(accd), _ptr(last),
                                     _ptr(g_rgb), _ptr(g_alpha), _ptr(g_depth), gstrides,
                                     _ptr(g_m2d), _ptr(g_con), _ptr(g_feat), _ptr(g_o), _threads())
        g_bg = None
        if ctx.needs_input_grad[4] and g_rgb is not None:
            g_bg = (g_rgb * T[..., None]).sum((0, 1)).to(ctx.bg_dtype)
        return g_m2d, g_con, g_feat, g_o.to(ctx.opac_dtype), g_bg, None, None, None, None, None


def _device_check(t: torch.Tensor) -> None:
    if t.device.type != "cpu":
        raise ValueError(f"the cpu backend needs CPU tensors, got {t.device}; use backend='auto'")


def render_cpu(means, quats, scales, opacities, colors, viewmat, K, width: int, height: int,
               sh_degree: int | None, background: torch.Tensor | None, near: float, far: float, on_invalid=None):
    """The cpu backend of :func:`anigs.render.rasterize` (inputs already shape-checked).

    ``on_invalid(flags)`` is called (and should raise) when the kernel finds non-finite
    inputs or out-of-range scales/opacities; None skips the checks.
    Returns rgb [H,W,3], alpha [H,W], depth [H,W], means2d [N,2], radii [N], valid [N], M.
    """
    _device_check(means)
    cam = camera_params(viewmat, K, near, far, on_invalid=on_invalid)
    deg = -1 if sh_degree is None else int(sh_degree)
    if not -1 <= deg <= 3:
        raise ValueError(f"SH degree must be in 0..3, got {deg}")
    means2d, conics, feats, rects, radii, valid = _Preprocess.apply(
        means, quats, scales, opacities, colors, cam, deg, width, height, on_invalid)
    if background is None:
        background = torch.zeros(3)
    info: dict = {}
    rgb, alpha, depth = _Composite.apply(means2d, conics, feats, opacities, background, valid, rects, width, height,
                                         info)
    return rgb, alpha, depth, means2d, radii, valid.view(torch.bool), info["num_visible"]


def project_cpu(means, quats, scales, opacities, viewmat, K, width: int, height: int,
                near: float = 0.01, far: float = 1e10, eps2d: float = EPS_2D):
    """Fused projection (same contract as ``projection.project_gaussians``, no cov2d).

    Returns means2d [N,2], conics [N,3], depths [N] (differentiable w.r.t. means, quats,
    scales), rects [N,4] int32, radii [N] int32, valid [N] bool.
    """
    _device_check(means)
    cam = camera_params(viewmat, K, near, far, eps2d)
    zeros = torch.zeros(means.shape[0], 3)
    m2d, con, feats, rects, radii, valid = _Preprocess.apply(
        means, quats, scales, opacities, zeros, cam, -1, int(width), int(height), None)
    return m2d, con, feats[:, 3], rects, radii, valid.view(torch.bool)


def _weights_fn():
    """``anigs_composite_weights`` of the loaded kernel, with its ctypes signature."""
    lib = render_kernel.load()
    fn = lib.anigs_composite_weights
    if fn.argtypes is None:
        P, I = render_kernel.ctypes.c_void_p, render_kernel.ctypes.c_int
        fn.argtypes = [I, I, I, I] + [P] * 8 + [I, P, I]
        fn.restype = I
    return lib, fn


def composite_weights_cpu(means, quats, scales, opacities, viewmat, K, width: int, height: int, factors,
                          near: float = 0.01, far: float = 1e10) -> torch.Tensor:
    """Per-Gaussian blend weights summed over pixels, forward only: [N, C] float64 with

        out[i, c] = sum_p w_i(p) factors[p, c],   w_i(p) = alpha_i(p) T_i(p),

    the weights of the image :func:`render_cpu` renders (same sort, binning, alpha cutoff and
    clamp, early termination), i.e. ``d rgb_c / d colour_i`` summed against ``factors`` as one
    backward pass would give it, without the gradients of the other inputs. ``factors``: a
    tensor or array [H,W,C] (C = 1..3) or [H,W] (C = 1). No autograd; the inputs are validated
    as by :func:`anigs.render.rasterize`. Deterministic and independent of the thread count.
    """
    _device_check(means)
    width, height, n = check_inputs("composite_weights_cpu", means, quats, scales, opacities, width, height)
    f = factors if torch.is_tensor(factors) else torch.from_numpy(np.asarray(factors))
    if f.ndim == 2:
        f = f[..., None]
    if f.ndim != 3 or tuple(f.shape[:2]) != (height, width) or not 1 <= f.shape[2] <= 3:
        raise ValueError(f"composite_weights_cpu: factors must be [H,W,C] = [{height},{width},1..3], "
                         f"got {tuple(f.shape)}")
    f = _f32(f.cpu())
    C = int(f.shape[2])
    lib, fn = _weights_fn()
    named = {"means": means, "quats": quats, "scales": scales, "opacities": opacities, "viewmat": viewmat, "K": K}

    def on_invalid(_flags: int) -> None:
        validate(named)
        raise ValueError("composite_weights_cpu: inputs are not finite in float32, or scales/opacities out of range")

    cam = camera_params(viewmat, K, near, far, on_invalid=on_invalid)
    m, q, s, o = (_f32(t) for t in (means, quats, scales, opacities))
    nt = _threads()
    nb = max(n, 1)
    colors = torch.zeros(nb, 3)
    means2d, conics, feats = torch.empty(nb, 2), torch.empty(nb, 3), torch.empty(nb, 4)
    rects, radii = torch.empty(nb, 4, dtype=torch.int32), torch.empty(nb, dtype=torch.int32)
    valid = torch.empty(nb, dtype=torch.uint8)
    flags = lib.anigs_preprocess(n, _ptr(cam), width, height, _ptr(m), _ptr(q), _ptr(s), _ptr(o), _ptr(colors),
                                 1, -1, _ptr(means2d), _ptr(conics), _ptr(feats), _ptr(rects), _ptr(radii),
                                 _ptr(valid), 1, nt)
    if flags:
        on_invalid(flags)
    order, gstart = torch.empty(nb, dtype=torch.int32), torch.empty(nb + 1, dtype=torch.int32)
    npairs = render_kernel.ctypes.c_longlong(0)
    M = lib.anigs_sort_count(n, _ptr(feats), _ptr(valid), _ptr(rects), _ptr(means2d), _ptr(conics), _ptr(o), width,
                             height, _ptr(order), _ptr(gstart), render_kernel.ctypes.byref(npairs), nt)
    if npairs.value >= 2**31:
        raise ValueError(f"composite_weights_cpu: {npairs.value} (tile, Gaussian) pairs exceed the int32 limit")
    out = torch.empty(nb, C, dtype=torch.float64)
    rc = fn(n, M, width, height, _ptr(order), _ptr(gstart), _ptr(means2d), _ptr(conics), _ptr(feats), _ptr(o),
            _ptr(rects), _ptr(f), C, _ptr(out), nt)
    if rc != 0:
        raise MemoryError("composite_weights_cpu: the kernel could not allocate its buffers")
    return out[:n]


def tile_pairs(means, quats, scales, opacities, viewmat, K, width: int, height: int) -> tuple[int, int]:
    """The (tile, Gaussian) pairs the kernel composites for this view, and the pairs of the
    Gaussians' whole pixel boxes (what binning by box alone would give): the work the tile
    culling of ``csrc/cull.cpp`` saves. Diagnostic (tests, ``benchmarks/step_profile.py``)."""
    _device_check(means)
    m2d, con, feats, rects, _, valid = _Preprocess.apply(
        means, quats, scales, opacities, torch.zeros(means.shape[0], 3), camera_params(viewmat, K, 0.01, 1e10), -1,
        int(width), int(height), None)
    n = means.shape[0]
    order, gstart = torch.empty(max(n, 1), dtype=torch.int32), torch.empty(n + 1, dtype=torch.int32)
    npairs = render_kernel.ctypes.c_longlong(0)
    render_kernel.load().anigs_sort_count(n, _ptr(feats), _ptr(valid), _ptr(rects), _ptr(m2d.detach()), _ptr(con.detach()),
                                   _ptr(_f32(opacities)), int(width), int(height), _ptr(order), _ptr(gstart),
                                   render_kernel.ctypes.byref(npairs), _threads())
    r = rects[valid.bool()].long()
    box = ((r[:, 2] - 1) // 16 - r[:, 0] // 16 + 1) * ((r[:, 3] - 1) // 16 - r[:, 1] // 16 + 1)
    return int(npairs.value), int(box.sum())
