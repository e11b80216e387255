"""Fast CPU compositing: tile-binned OpenMP kernel with a hand-written backward.

Same semantics as :func:`anigs.render.torch_backend.composite_torch`; float32 only.
"""
from __future__ import annotations

import torch

from anigs.render import _build


def _ptr(t: torch.Tensor) -> int:
    return t.data_ptr()


def _threads() -> int:
    return max(1, torch.get_num_threads())


class _Composite(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, feats, opacities, rects, width: int, height: int):
        lib = _build.load()
        ctx.dtypes = (means2d.dtype, conics.dtype, feats.dtype, opacities.dtype)
        M, C = feats.shape
        if C > 32:
            raise ValueError(f"cpu backend supports at most 32 feature channels, got {C}")
        means2d, conics, feats, opacities = (t.detach().float().contiguous() for t in (means2d, conics, feats, opacities))
        rects = rects.to(torch.int32).contiguous()
        counts = torch.empty(M, dtype=torch.int32)
        lib.anigs_tile_counts(M, _ptr(rects), width, height, _ptr(counts))
        gstart = (torch.cumsum(counts, 0, dtype=torch.int64) - counts).to(torch.int32)
        npairs = int(counts.sum())
        ntiles = ((width + 15) // 16) * ((height + 15) // 16)
        tile_offsets = torch.empty(ntiles + 1, dtype=torch.int32)
        tile_splats = torch.empty(max(npairs, 1), dtype=torch.int32)
        pair_slots = torch.empty(max(npairs, 1), dtype=torch.int32)
        lib.anigs_bin(M, _ptr(rects), width, height, _ptr(gstart), _ptr(tile_offsets), _ptr(tile_splats), _ptr(pair_slots))
        out_feat = torch.empty(height, width, C)
        out_T = torch.empty(height, width)
        out_last = torch.empty(height, width, dtype=torch.int32)
        lib.anigs_forward(M, C, width, height, _ptr(means2d), _ptr(conics), _ptr(feats), _ptr(opacities),
                          _ptr(rects), _ptr(tile_offsets), _ptr(tile_splats),
                          _ptr(out_feat), _ptr(out_T), _ptr(out_last), _threads())
        ctx.save_for_backward(means2d, conics, feats, opacities, rects, counts, gstart,
                              tile_offsets, tile_splats, pair_slots, out_T, out_last)
        ctx.size = (width, height, npairs)
        ctx.mark_non_differentiable(out_last)
        return out_feat, out_T, out_last

    @staticmethod
    def backward(ctx, g_feat, g_T, _g_last):
        lib = _build.load()
        (means2d, conics, feats, opacities, rects, counts, gstart,
         tile_offsets, tile_splats, pair_slots, out_T, out_last) = ctx.saved_tensors
        width, height, npairs = ctx.size
        M, C = feats.shape
        D = 6 + C
        g_feat = (torch.zeros(height, width, C) if g_feat is None else g_feat).float().contiguous()
        g_T = (torch.zeros(height, width) if g_T is None else g_T).float().contiguous()
        pair_grads = torch.zeros(max(npairs, 1), D)
        lib.anigs_backward(M, C, width, height, _ptr(means2d), _ptr(conics), _ptr(feats), _ptr(opacities),
                           _ptr(rects), _ptr(tile_offsets), _ptr(tile_splats), _ptr(out_T), _ptr(out_last),
                           _ptr(g_feat), _ptr(g_T), _ptr(pair_grads), _threads())
        grads = torch.empty(M, D)
        lib.anigs_reduce(M, D, _ptr(gstart), _ptr(counts), _ptr(pair_slots), _ptr(pair_grads), _ptr(grads), _threads())
        dm, dq, df, do = ctx.dtypes
        return (grads[:, 0:2].to(dm), grads[:, 2:5].to(dq), grads[:, 6:].to(df), grads[:, 5].to(do),
                None, None, None)


class _Project(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, quats, scales, opacities, cam, width: int, height: int):
        lib = _build.load()
        n = means.shape[0]
        ctx.dtypes = (means.dtype, quats.dtype, scales.dtype)
        means, quats, scales, opacities = (t.detach().float().contiguous() for t in (means, quats, scales, opacities))
        means2d, conics = torch.empty(n, 2), torch.empty(n, 3)
        depths = torch.empty(n)
        rects = torch.empty(n, 4, dtype=torch.int32)
        radii = torch.empty(n, dtype=torch.int32)
        valid = torch.empty(n, dtype=torch.uint8)
        lib.anigs_project_forward(n, _ptr(cam), width, height, _ptr(means), _ptr(quats), _ptr(scales), _ptr(opacities),
                                  _ptr(means2d), _ptr(conics), _ptr(depths), _ptr(rects), _ptr(radii), _ptr(valid),
                                  _threads())
        ctx.save_for_backward(means, quats, scales, valid, cam)
        ctx.size = (width, height)
        ctx.mark_non_differentiable(rects, radii, valid)
        return means2d, conics, depths, rects, radii, valid

    @staticmethod
    def backward(ctx, g_m2d, g_con, g_dep, _r, _rad, _v):
        lib = _build.load()
        means, quats, scales, valid, cam = ctx.saved_tensors
        width, height = ctx.size
        n = means.shape[0]
        z = lambda *s: torch.zeros(*s)
        g_m2d = (z(n, 2) if g_m2d is None else g_m2d).float().contiguous()
        g_con = (z(n, 3) if g_con is None else g_con).float().contiguous()
        g_dep = (z(n) if g_dep is None else g_dep).float().contiguous()
        gm, gq, gs = torch.empty(n, 3), torch.empty(n, 4), torch.empty(n, 3)
        lib.anigs_project_backward(n, _ptr(cam), width, height, _ptr(means), _ptr(quats), _ptr(scales), _ptr(valid),
                                   _ptr(g_m2d), _ptr(g_con), _ptr(g_dep), _ptr(gm), _ptr(gq), _ptr(gs), _threads())
        dm, dq, ds = ctx.dtypes
        return gm.to(dm), gq.to(dq), gs.to(ds), None, None, None, None


def project_cpu(means, quats, scales, opacities, viewmat, K, width: int, height: int,
                near: float = 0.01, far: float = 1e10, eps2d: float = 0.3):
    """Fused projection (same contract as ``projection.project_gaussians``, no cov2d).

    Returns means2d [N,2], conics [N,3], depths [N] (differentiable w.r.t. means, quats,
    scales), rects [N,4] int32, radii [N] int32, valid [N] bool.
    """
    if means.device.type != "cpu":
        raise ValueError(f"the cpu backend needs CPU tensors, got {means.device}; use backend='auto'")
    v = viewmat.detach().double().cpu()
    k = K.detach().double().cpu()
    cam = torch.cat([v[:3, :3].reshape(-1), v[:3, 3], torch.stack([k[0, 0], k[1, 1], k[0, 2], k[1, 2]]),
                     torch.tensor([near, min(far, 3e38), eps2d], dtype=torch.float64)]).float().contiguous()
    m2d, con, dep, rects, radii, valid = _Project.apply(means, quats, scales, opacities, cam, int(width), int(height))
    return m2d, con, dep, rects, radii, valid.bool()


def composite_cpu(
    means2d: torch.Tensor, conics: torch.Tensor, feats: torch.Tensor, opacities: torch.Tensor,
    rects: torch.Tensor, width: int, height: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Composite M depth-sorted splats; same contract as ``composite_torch``.

    Returns accumulated features [H,W,C] and final transmittance [H,W].
    """
    if means2d.device.type != "cpu":
        raise ValueError(f"the cpu backend needs CPU tensors, got {means2d.device}; use backend='auto'")
    feat, T, _ = _Composite.apply(means2d, conics, feats, opacities, rects, int(width), int(height))
    return feat, T
