"""Held-out PSNR of the static fit with and without the needle regulariser (static.regularize).

    python benchmarks/needles.py --sfm results/demo/sfm [--iterations 1000] [--background R G B]
    python benchmarks/needles.py --sparse [--iterations 1000] [--png OUT.png]

``--sfm DIR``: a workflow's SfM folder (``images/``, ``cameras.json``, ``points.npz``), the
static stage's inputs. ``--sparse``: the synthetic sparse capture of
:func:`anigs.synth.floaters.sparse_capture_config` (11 photos walking along the courtyard's
facade, looking up at it, sky above), rendered from its ground truth; the points are every 8th
ground-truth centre with 2 cm noise (a pseudo-SfM cloud: nothing in the sky) and the fit's
background is black, as for a photo scene, so the sky must be fitted by Gaussians.

Fits once with ``static.regularize.enabled: false`` and once with the defaults (or the
``--set KEY=VALUE`` overrides of ``static.regularize``), same seed and inputs, and prints per
fit: held-out PSNR / SSIM, Gaussians, how many have a largest/middle scale ratio above 10, how
many no training photo resolves (largest std dev > 8% of the width in every photo holding it),
and the seconds. ``--png`` writes the first held-out photo, and each fit's render of it, side by side.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch


def _sparse_inputs():
    from anigs.synth.capture import camera_path, render_image
    from anigs.synth.floaters import sparse_capture_config
    from anigs.synth.build import build_scene

    cfg = sparse_capture_config(num_gaussians=30000, width=320, height=240)
    gt = build_scene(cfg)
    cams = camera_path(cfg.capture, cfg.seed)
    imgs = [torch.from_numpy(render_image(gt, c, cfg.capture.background)) for c in cams]
    rng = np.random.default_rng(0)
    pts = gt.means.numpy()[::8].astype(np.float64)
    pts = pts + rng.normal(0, 0.02, pts.shape)
    cols = gt.rgb.numpy()[::8]
    return imgs, cams, pts, cols, (0.0, 0.0, 0.0)


def _sfm_inputs(sfm: Path):
    from anigs.images import load_inputs
    from anigs.stages.sfm import Outputs as SfmOutputs

    out = SfmOutputs(sfm)
    imgs, cams = load_inputs(out.path("images"), out.path("cameras"))
    pts, cols = out.points()
    return imgs, cams, pts, cols, None


def _stats(g, cams, holdout) -> dict:
    from anigs.static.regularize import min_screen_sigma

    s = g.scales.sort(1).values
    needles = int((s[:, 2] / s[:, 1] > 10).sum())
    train = [c for i, c in enumerate(cams) if i not in holdout]
    best = min_screen_sigma(g.means, g.log_scales, train, [(c.torch_viewmat(), c.torch_K()) for c in train])
    return {"needles_over_10": needles, "unresolved_8pct": int((best > 0.08).sum())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--sfm", type=Path, help="a workflow's sfm folder")
    src.add_argument("--sparse", action="store_true", help="the synthetic sparse facade capture (11 photos)")
    ap.add_argument("--iterations", type=int, default=1000)
    ap.add_argument("--background", type=float, nargs=3, default=None, help="fit background (default: black)")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="static.regularize overrides")
    ap.add_argument("--skip-off", action="store_true", help="fit only with the regulariser (ablations)")
    ap.add_argument("--png", type=Path, default=None)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from anigs.static.fit import StaticConfig, render_params, to_params, fit_static, split_holdout

    imgs, cams, pts, cols, bg = _sparse_inputs() if args.sparse else _sfm_inputs(args.sfm)
    bg = tuple(args.background) if args.background else (bg or (0.0, 0.0, 0.0))
    over = {k: json.loads(v) for k, v in (s.split("=", 1) for s in args.set)}
    _, test = split_holdout(len(imgs), 8)
    out, renders = {}, []
    for name, reg in (("off", {"enabled": False}), ("on", over))[int(args.skip_off):]:
        cfg = StaticConfig.from_dict({"iterations": args.iterations, "background": list(bg), "regularize": reg})
        t = time.perf_counter()
        g, m = fit_static(imgs, cams, pts, cols, cfg, progress=False)
        row = {"test_psnr": round(m["test_psnr"], 3), "test_ssim": round(m["test_ssim"], 4),
               "num_gaussians": g.num, **_stats(g, cams, set(test)), "seconds": round(time.perf_counter() - t, 1)}
        out[name] = row
        print(f"regularize {name}: held-out PSNR {row['test_psnr']:.2f} dB, SSIM {row['test_ssim']:.3f}, "
              f"{row['num_gaussians']} Gaussians, {row['needles_over_10']} with largest/middle scale > 10, "
              f"{row['unresolved_8pct']} unresolved, {row['seconds']:.0f} s", flush=True)
        if args.png is not None and test:
            with torch.no_grad():
                rgb, _, _ = render_params(to_params(g, torch.device("cpu")), cams[test[0]], g.sh_degree,
                                    torch.tensor(bg, dtype=torch.float32), "auto")
            renders.append(rgb.clamp(0, 1).numpy())
    if "off" in out:
        print(f"held-out PSNR change: {out['on']['test_psnr'] - out['off']['test_psnr']:+.2f} dB "
              f"({len(test)} held-out of {len(imgs)} photos)")
    if args.json:
        print(json.dumps(out))
    if args.png is not None and renders:
        import cv2

        strip = np.concatenate([imgs[test[0]].numpy()] + renders, 1)
        args.png.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(args.png), (strip[..., ::-1] * 255).round().astype(np.uint8))
        print(f"wrote {args.png} (photo | regularize off | on)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
