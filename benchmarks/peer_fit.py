"""A peer trainer beside anigs's static fit, on the same photos, split and Gaussian budget (issue 46).

OpenSplat (a real open-source 3DGS trainer, built for the CPU by ``../shared/tools/build-opensplat.sh``)
trains on the sfm folder's training photos (a copy of its COLMAP model without the held-out photos:
anigs's split, every ``--holdout-every``-th photo by name), saving its splat every tenth of
``--eval-every`` steps (so that its curve can be read at anigs's seconds); then anigs's static fit (``anigs.static.fit.fit_static``) trains on the same photos for the same
steps, its densification capped at OpenSplat's final Gaussian count, evaluating at the same steps. Both
are measured the same way: each saved splat is brought into the sfm folder's frame (OpenSplat's through
its cameras.json, :mod:`anigs.static.imported`) and rendered with anigs's rasterizer on the held-out
photos, at the photos' size, onto the background each trained with (OpenSplat's fixed colour; anigs's
evaluation grey, or the scene's fixed sky with ``--background``).

Printed: per method the threads, steps, median ms per step, final Gaussians, held-out PSNR at equal steps
(the last) and at equal seconds (each curve read at the shorter run's training seconds), and both curves.
Timings are wall seconds of training on a machine that may be shared: the load average is printed.

    python benchmarks/peer_fit.py --sfm results/demo/sfm --opensplat /work/os-build/opensplat --steps 2000 \\
        --eval-every 250 --threads 2 --background 0.6 0.75 0.9 --out /tmp/peer_demo
"""
from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: F401,E402  (before pycolmap: their zlib builds clash the other way round)
import numpy as np  # noqa: E402
import torch  # noqa: E402

from anigs.formats.trainers import OPENSPLAT_BACKGROUND, read_trainer_cameras  # noqa: E402
from anigs.gaussians import load_ply  # noqa: E402
from anigs.geometry.transform import transform_gaussians  # noqa: E402
from anigs.images import load_inputs  # noqa: E402
from anigs.sfm.model import load_points  # noqa: E402
from anigs.static.fit import StaticConfig, fit_static  # noqa: E402
from anigs.static.imported import cameras_candidate, measure  # noqa: E402
from anigs.static.init import split_holdout  # noqa: E402


def train_folder(sfm: Path, held: list[str], out: Path) -> Path:
    """A COLMAP folder (images/ linked, sparse/0 without the held-out photos) for the peer."""
    import pycolmap

    rec = pycolmap.Reconstruction(str(sfm / "sparse" / "0"))
    for i in list(rec.reg_image_ids()):
        if rec.images[i].name in held:
            rec.deregister_frame(rec.images[i].frame_id)
    (out / "sparse" / "0").mkdir(parents=True, exist_ok=True)
    rec.write(str(out / "sparse" / "0"))
    if not (out / "images").exists():
        (out / "images").symlink_to((sfm / "images").resolve())
    return out


def run_opensplat(binary: Path, colmap: Path, steps: int, every: int, threads: int, out: Path) -> dict:
    """Train; returns {step: wall seconds since the first step began} and the command."""
    out.mkdir(parents=True, exist_ok=True)
    cmd = [str(binary), str(colmap), "-n", str(steps), "--cpu", "--num-downscales", "0", "-s", str(every),
           "-o", str(out / "splat.ply")]
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    t0, stamps = time.perf_counter(), {}
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env) as p:
        log = []
        for line in p.stdout:
            log.append(line)
            m = re.match(r"Step (\d+):", line)
            if m:
                stamps[int(m.group(1))] = time.perf_counter() - t0
    (out / "opensplat.log").write_text("".join(log))
    if p.returncode != 0:
        raise RuntimeError(f"OpenSplat failed ({p.returncode}): {''.join(log[-20:])}")
    return {"stamps": stamps, "command": " ".join(cmd), "wall_s": time.perf_counter() - t0}


def opensplat_curve(out: Path, steps: int, every: int, cams, imgs, test_idx, stamps: dict) -> list[dict]:
    """Held-out PSNR of each saved OpenSplat splat (in the sfm frame through its cameras.json)."""
    cand, _ = cameras_candidate(read_trainer_cameras(out / "cameras.json"), cams)
    s = cand.to_sfm
    bg = torch.tensor(OPENSPLAT_BACKGROUND)
    curve = []
    for k in sorted(set(range(every, steps + 1, every)) | {steps}):
        f = out / ("splat.ply" if k == steps else f"splat_{k}.ply")
        if not f.exists():
            continue
        g = transform_gaussians(load_ply(f), s.scale, s.R, s.t)
        r = measure(g, [imgs[i] for i in test_idx], [cams[i] for i in test_idx], bg)
        first = stamps.get(1, 0.0)
        curve.append({"step": k, "seconds": stamps.get(k, float("nan")) - first, "test_psnr": r["psnr"],
                      "gaussians": g.num})
    return curve


def _at(curve: list[dict], seconds: float) -> float:
    """The curve's held-out PSNR at ``seconds`` (the last point not after it)."""
    before = [c for c in curve if c["seconds"] <= seconds + 1e-9]
    return before[-1]["test_psnr"] if before else float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sfm", type=Path, required=True, help="an anigs sfm folder (a COLMAP project)")
    ap.add_argument("--opensplat", type=Path, help="the OpenSplat binary (without it: anigs only)")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--eval-every", type=int, default=250)
    ap.add_argument("--holdout-every", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--background", type=float, nargs=3, help="anigs's fixed background (a synthetic sky)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.threads)
    imgs_u8, cams = load_inputs(args.sfm / "images", args.sfm / "cameras.json", compact=True)
    imgs = [i.float() / 255.0 for i in imgs_u8]
    pts, cols = load_points(args.sfm / "points.npz")
    train_idx, test_idx = split_holdout(len(cams), args.holdout_every)
    held = [cams[i].name for i in test_idx]
    load = [os.getloadavg()[0]]
    rows, curves = [], {}
    budget = None
    if args.opensplat:
        colmap = train_folder(args.sfm, held, args.out / "colmap_train")
        fine = max(d for d in range(1, args.eval_every + 1) if args.eval_every % d == 0 and d <= max(1, args.eval_every // 10))
        run = run_opensplat(args.opensplat, colmap, args.steps, fine, args.threads, args.out / "opensplat")
        curve = opensplat_curve(args.out / "opensplat", args.steps, fine, cams, imgs, test_idx, run["stamps"])
        st = run["stamps"]
        ms = np.median(np.diff([st[k] for k in sorted(st)])) * 1000
        budget = curve[-1]["gaussians"]
        curves["opensplat"] = curve
        rows.append({"method": "OpenSplat 1.1.5 (CPU)", "threads": args.threads, "steps": args.steps,
                     "ms_per_step": ms, "train_s": curve[-1]["seconds"], "gaussians": budget,
                     "test_psnr": curve[-1]["test_psnr"]})
        print(run["command"])
    bg = args.background
    cfg = StaticConfig.from_dict({"iterations": args.steps, "eval_every": args.eval_every, "max_side": 0,
                               "holdout_every": args.holdout_every, "plateau_db": 0, "seed": 0,
                               "background": list(bg) if bg else "random",
                               "densify": {"max_gaussians": budget} if budget else {}})
    g, m = fit_static(imgs_u8, cams, pts, cols, cfg, progress=False)
    curve = [{"step": c["iteration"], "seconds": c["train_seconds"], "test_psnr": c["test_psnr"],
              "gaussians": c.get("num_gaussians")} for c in m["curve"] if c["iteration"] > 0]
    curves["anigs"] = curve
    rows.append({"method": "anigs static fit (CPU)", "threads": torch.get_num_threads(), "steps": m["iterations"],
                 "ms_per_step": m["step_ms_median"], "train_s": m["train_seconds"], "gaussians": m["num_gaussians"],
                 "test_psnr": m["test_psnr"]})
    load.append(os.getloadavg()[0])
    equal = min(r["train_s"] for r in rows)
    for r, name in zip(rows, curves):
        r["test_psnr_at_equal_s"] = _at(curves[name], equal)
    size = f"{cams[0].width}x{cams[0].height}"
    print(f"\n{len(train_idx)} training and {len(test_idx)} held-out photos (every {args.holdout_every}th), "
          f"{size}; load average {load[0]:.1f} -> {load[1]:.1f}; anigs background "
          f"{'grey (random while training)' if not bg else bg}, OpenSplat's {OPENSPLAT_BACKGROUND}")
    print("| method | threads | steps | ms/step (median) | train s | Gaussians | held-out PSNR at equal steps "
          f"| held-out PSNR at {equal:.0f} s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['threads']} | {r['steps']} | {r['ms_per_step']:.0f} | {r['train_s']:.0f} | "
              f"{r['gaussians']:,} | {r['test_psnr']:.2f} | {r['test_psnr_at_equal_s']:.2f} |")
    for name, curve in curves.items():
        print(f"{name}: " + ", ".join(f"{c['step']}: {c['test_psnr']:.2f} dB @ {c['seconds']:.0f} s" for c in curve
                                      if c["step"] % args.eval_every == 0 or c is curve[-1]))
    (args.out / "peer_fit.json").write_text(json.dumps({"rows": rows, "curves": curves, "size": size,
                                                        "held_out": held, "load": load}, indent=1))
    shutil.rmtree(args.out / "colmap_train", ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
