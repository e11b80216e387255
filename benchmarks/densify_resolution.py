"""Does densification's gradient test depend on the image size? The same capture fitted at two
photo sizes: how many Gaussians pass the gradient threshold at the first densification steps.

    python benchmarks/densify_resolution.py --sfm RESULTS/photos/sfm [--scales 1.0,0.5] [--steps 600]
        [--threshold 0.0002] [--threads 2]

For each scale the photos are resized (area interpolation) and the cameras scaled with them; the
fit runs ``--steps`` steps with densification every 100 steps from step 300 and a budget large
enough never to bind. Prints, per scale and densification step, the Gaussians before it and how
many passed the threshold (cloned + split). A resolution-independent test passes about the same
share at every scale.
"""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


class _Grab(logging.Handler):
    def __init__(self):
        super().__init__(logging.DEBUG)
        self.rows = []

    def emit(self, record):
        if record.getMessage().startswith("densify step"):
            self.rows.append(record.args[1])


def main() -> None:
    from _scaled_capture import load_sfm_capture, scaled_view

    from anigs.sfm.model import load_points
    from anigs.static.densify import DensifyConfig
    from anigs.static.fit import StaticConfig, fit_static

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True, help="an sfm stage folder")
    ap.add_argument("--scales", default="1.0,0.5")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--threshold", type=float, default=0.0002)
    args, sfm, imgs, cams = load_sfm_capture(ap)
    pts, cols = load_points(sfm.path("points"))
    grab = _Grab()
    lg = logging.getLogger("anigs.static.densify")
    lg.setLevel(logging.DEBUG)
    lg.addHandler(grab)
    print(f"{len(imgs)} photos at {cams[0].width}x{cams[0].height}, {len(pts)} SfM points, threshold {args.threshold}")
    print("| scale | size | step | Gaussians after | cloned | split | held-out PSNR |")
    print("|---|---|---|---|---|---|---|")
    for scale in [float(s) for s in args.scales.split(",")]:
        s_imgs, s_cams = [], []
        for im, c in zip(imgs, cams):
            x, cs = scaled_view(im, c, scale)
            s_imgs.append(x.clamp(0, 1))
            s_cams.append(cs)
        grab.rows.clear()
        cfg = StaticConfig(iterations=args.steps, eval_every=0, plateau_db=0.0,
                        densify=DensifyConfig(start=300, every=100, stop=args.steps, stop_fraction=1.0,
                                              grad_threshold=args.threshold, max_gaussians=10_000_000))
        _, m = fit_static(s_imgs, s_cams, pts, cols, cfg, progress=False)
        for r in grab.rows:
            print(f"| {scale:g} | {s_cams[0].width}x{s_cams[0].height} | {r['step']} | {r['num']} | {r['cloned']} "
                  f"| {r['split']} | {m['test_psnr']:.2f} |")


if __name__ == "__main__":
    main()
