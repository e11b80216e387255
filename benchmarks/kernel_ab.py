"""Two or more builds of the cpu rasterizer's kernel, call by call in one process (paired timing).

    python benchmarks/kernel_ab.py --sfm RESULTS/photos/sfm --ply MODEL.ply --size 987x740 --gaussians 100000
        old=/path/to/old/checkout/anigs/render/csrc new=anigs/render/csrc [--reps 3]

Each NAME=DIR is a kernel source folder (``raster.cpp`` and what it includes), compiled with the
flags of ``anigs.render.kernel`` into a temporary library; ABI 4 (box binning, before issue 34) and
ABI 5 (tile culling) are both understood. On four of the capture's views at ``--size``, with the model
grown to ``--gaussians`` (as ``benchmarks/step_profile.py``), the same projected splats go through
each build's depth sort + tile count, compositing forward and backward (an upstream rgb gradient),
the builds taking turns call by call on one thread, so a comparison holds while a shared machine's
speed drifts. Prints process CPU medians per part, the (tile, splat) pairs, each build's total
against the first one's, paired call by call, and whether their images are bit-identical.
"""
from __future__ import annotations

import argparse
import ctypes
import hashlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

P, I = ctypes.c_void_p, ctypes.c_int
LL = ctypes.POINTER(ctypes.c_longlong)


def build(name_dir: str, out_dir: Path):
    """(name, library, ABI) of one NAME=DIR build."""
    from anigs.render import kernel as render_kernel

    name, folder = name_dir.split("=", 1)
    srcs = sorted(Path(folder).glob("*.cpp"))
    key = hashlib.sha256(b"".join(p.read_bytes() for p in srcs)).hexdigest()[:12]
    out = out_dir / f"raster_{key}.so"
    if not out.exists():
        flags = render_kernel.FLAGS + render_kernel.arch_flags() + render_kernel.thread_flags()
        subprocess.run(["c++", *flags, str(Path(folder) / "raster.cpp"), "-o", str(out)], check=True)
    lib = ctypes.CDLL(str(out))
    abi = lib.anigs_abi_version()
    if abi not in (4, 5):
        raise SystemExit(f"{name}: kernel ABI {abi} is not 4 or 5")
    lib.anigs_preprocess.argtypes = [I, P, I, I, P, P, P, P, P, I, I, P, P, P, P, P, P, I, I]
    lib.anigs_preprocess.restype = I
    cull = 1 if abi == 5 else 0
    lib.anigs_sort_count.argtypes = [I, P, P, P] + [P] * (3 * cull) + [I, I, P, P, LL] + [I] * cull
    lib.anigs_sort_count.restype = I
    lib.anigs_composite_forward.argtypes = [I, I, I] + [P] * (18 + cull) + [I]
    lib.anigs_composite_backward.argtypes = [I, I, I, I] + [P] * (19 + cull) + [I]
    return name, lib, abi


def project(lib, g, cam, W: int, H: int):
    """Projected splats of the Gaussians ``g`` (SH degree 3): means2d, conics, feats, rects, valid, opacities."""
    import torch

    from anigs.render.cpu_backend import camera_params

    n = g.num
    m, q, s = g.means.contiguous(), g.quats.contiguous(), g.log_scales.exp().contiguous()
    o, sh = torch.sigmoid(g.opacity_logits).contiguous(), g.sh.contiguous()
    cp = camera_params(cam.torch_viewmat(), cam.torch_K(), 0.01, 1e10)
    m2d, con, feats = torch.empty(n, 2), torch.empty(n, 3), torch.empty(n, 4)
    rects, radii = torch.empty(n, 4, dtype=torch.int32), torch.empty(n, dtype=torch.int32)
    valid = torch.empty(n, dtype=torch.uint8)
    ptr = lambda t: t.data_ptr()
    lib.anigs_preprocess(n, ptr(cp), W, H, ptr(m), ptr(q), ptr(s), ptr(o), ptr(sh), 16, 3, ptr(m2d), ptr(con),
                         ptr(feats), ptr(rects), ptr(radii), ptr(valid), 0, 1)
    return m2d, con, feats, rects, valid, o


def run(lib, abi: int, view, grgb, W: int, H: int):
    """One sort + forward + backward: (sort ms, forward ms, backward ms, pairs, rgb)."""
    import torch

    m2d, con, feats, rects, valid, o = view
    n = m2d.shape[0]
    ptr = lambda t: t.data_ptr()
    order, gstart = torch.empty(n, dtype=torch.int32), torch.empty(n + 1, dtype=torch.int32)
    npairs = ctypes.c_longlong(0)
    cull = [ptr(m2d), ptr(con), ptr(o)] if abi == 5 else []
    t0 = time.process_time()
    M = lib.anigs_sort_count(n, ptr(feats), ptr(valid), ptr(rects), *cull, W, H, ptr(order), ptr(gstart),
                             ctypes.byref(npairs), *([1] if abi == 5 else []))
    t1 = time.process_time()
    npr, nt = npairs.value, ((W + 15) // 16) * ((H + 15) // 16)
    recs, toff = torch.empty(max(M, 1), 16), torch.empty(nt + 1, dtype=torch.int32)
    ts, tr, ps = (torch.empty(max(npr, 1), dtype=torch.int32) for _ in range(3))
    rgb, alpha, depth, T, accd = torch.empty(H, W, 3), torch.empty(H, W), torch.empty(H, W), torch.empty(H, W), \
        torch.empty(H, W)
    last = torch.empty(H, W, dtype=torch.int32)
    bins = [ptr(ts), ptr(tr)] if abi == 5 else [ptr(ts)]
    bg = torch.tensor([0.3, 0.5, 0.7])
    t2 = time.process_time()
    lib.anigs_composite_forward(M, W, H, ptr(order), ptr(gstart), ptr(m2d), ptr(con), ptr(feats), ptr(o), ptr(rects),
                                ptr(bg), ptr(recs), ptr(toff), *bins, ptr(ps), ptr(rgb), ptr(alpha), ptr(depth),
                                ptr(T), ptr(accd), ptr(last), 1)
    t3 = time.process_time()
    gm, gc, gf, go = torch.empty(n, 2), torch.empty(n, 3), torch.empty(n, 4), torch.empty(n)
    strides = (ctypes.c_longlong * 7)(*grgb.stride(), 0, 0, 0, 0)
    t4 = time.process_time()
    lib.anigs_composite_backward(n, M, W, H, ptr(order), ptr(gstart), ptr(valid), ptr(recs), ptr(toff), *bins,
                                 ptr(ps), ptr(bg), ptr(T), ptr(accd), ptr(last), ptr(grgb), None, None, strides,
                                 ptr(gm), ptr(gc), ptr(gf), ptr(go), 1)
    t5 = time.process_time()
    return (t1 - t0) * 1e3, (t3 - t2) * 1e3, (t5 - t4) * 1e3, npr, rgb


def main() -> None:
    import numpy as np
    import torch

    from anigs.gaussians import load_ply
    from anigs.images import load_inputs
    from anigs.stages.sfm import Outputs as SfmOutputs
    from step_profile import grow

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True)
    ap.add_argument("--ply", required=True)
    ap.add_argument("--size", default="987x740")
    ap.add_argument("--gaussians", type=int, default=100000)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("builds", nargs="+", help="NAME=DIR kernel source folders; the first is the reference")
    args = ap.parse_args()
    torch.set_num_threads(1)
    W, H = (int(v) for v in args.size.lower().split("x"))
    tmp = Path(tempfile.mkdtemp(prefix="kernel_ab_"))
    builds = [build(b, tmp) for b in args.builds]
    sfm = SfmOutputs(args.sfm)
    _, cams = load_inputs(sfm.path("images"), sfm.path("cameras"))
    g = grow(load_ply(args.ply), args.gaussians, torch.Generator().manual_seed(0))
    views = [project(builds[0][1], g, cams[v].scaled(W, H), W, H) for v in range(0, min(len(cams), 16), 4)]
    grgb = torch.randn(H, W, 3, generator=torch.Generator().manual_seed(3)) * 1e-3
    res: dict[str, list] = {name: [] for name, _, _ in builds}
    images: dict[tuple[str, int], torch.Tensor] = {}
    for _ in range(args.reps):
        for vi, view in enumerate(views):
            for name, lib, abi in builds:
                *t, rgb = run(lib, abi, view, grgb, W, H)
                res[name].append(t)
                images.setdefault((name, vi), rgb)
    print(f"{W}x{H}, {g.num:,} Gaussians, {args.reps} x {len(views)} views, one thread; process CPU ms, medians:")
    for name, rows in res.items():
        a = np.array(rows)
        med = np.median(a[:, :3], 0)
        print(f"  {name:10s} sort {med[0]:7.2f}  forward {med[1]:7.2f}  backward {med[2]:7.2f}  total {med.sum():7.2f}"
              f"  pairs {int(np.median(a[:, 3])):,}")
    ref = builds[0][0]
    for name, _, _ in builds[1:]:
        ratio = [sum(x[:3]) / sum(y[:3]) for x, y in zip(res[name], res[ref])]
        same = all(torch.equal(images[(name, vi)], images[(ref, vi)]) for vi in range(len(views)))
        print(f"  {name}/{ref}: paired ratio median {np.median(ratio):.3f} (min {min(ratio):.3f}, max {max(ratio):.3f});"
              f" images bit-identical: {same}")


if __name__ == "__main__":
    main()
