"""Why a static fit's held-out PSNR is low: per photo, what exposure, pose and coverage explain.

    python benchmarks/heldout_diagnosis.py --sfm RESULTS/photos/sfm --static RESULTS/photos/static
        [--out diagnosis.png] [--threads 2]

For every photo (train and held-out, as ``static/metrics.json`` names them) at the fit's photo size:
the render's PSNR against the photo (the fit's grey evaluation background); the PSNR after the best
per-photo affine colour map of the render (``photo ~ M render + c``, 3x3 + 3 by least squares: what
exposure and white balance alone explain); the PSNR of the render with the SH degree-0 colours only
(view-dependent colour that fits the training photos only); the PSNR after the homography that best
aligns the render to the photo (what a global misregistration explains); the PSNR of the photo
blurred by a 2-px Gaussian (what an aligned but blurry render would score); the share of opaque
pixels (alpha > 0.9; in the rows); the median relative error of the render's depth at the photo's observed SfM
points; the SfM's mean reprojection error and observation count of the photo
(``sfm/sparse/0``); and the distance to the nearest training camera (scene units) with the angle
between their viewing directions. Prints a Markdown table and writes a contact sheet of the
held-out photos: render | photo | |error| (x3) | alpha, one row each.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402

from anigs.gaussians import load_ply  # noqa: E402
from anigs.images import load_inputs  # noqa: E402
from anigs.render import rasterize  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402


def _psnr(a, b, mask=None) -> float:
    import numpy as np

    d = (a - b) ** 2
    mse = float(d[mask].mean()) if mask is not None else float(d.mean())
    return float(10 * np.log10(1.0 / max(mse, 1e-12)))


def _affine(render, photo):
    """The render mapped by the least-squares 3x3 + 3 colour map onto the photo."""
    import numpy as np

    X = np.concatenate([render.reshape(-1, 3), np.ones((render.shape[0] * render.shape[1], 1))], 1)
    coef, *_ = np.linalg.lstsq(X, photo.reshape(-1, 3), rcond=None)
    return np.clip(X @ coef, 0, 1).reshape(photo.shape), coef


def _aligned_psnr(render, photo) -> float:
    """PSNR after the homography that best aligns the render to the photo (OpenCV's ECC on grey
    images), over the pixels the warp covers; NaN when ECC does not converge."""
    import cv2
    import numpy as np

    grey = lambda x: cv2.cvtColor((x * 255).astype(np.uint8), cv2.COLOR_RGB2GRAY).astype(np.float32) / 255
    warp = np.eye(3, dtype=np.float32)
    try:
        _, warp = cv2.findTransformECC(grey(photo), grey(render), warp, cv2.MOTION_HOMOGRAPHY,
                                       (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-6), None, 5)
    except cv2.error:
        return float("nan")
    h, w = photo.shape[:2]
    flags = cv2.INTER_LINEAR + cv2.WARP_INVERSE_MAP
    moved = cv2.warpPerspective(render.astype(np.float32), warp, (w, h), flags=flags)
    cover = cv2.warpPerspective(np.ones((h, w), np.float32), warp, (w, h), flags=flags) > 0.99
    return _psnr(moved, photo, cover)


def _reprojection(sparse: Path) -> tuple[dict[str, tuple[float, int]], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per image name: (mean reprojection error in pixels, observations); its observed SfM points as
    rows (x, y, depth) in the SfM's own frame and pixels; and its projection centre."""
    import pycolmap

    rec = pycolmap.Reconstruction(str(sparse))
    errors, obs, centres = {}, {}, {}
    for im in rec.images.values():
        cam = rec.cameras[im.camera_id]
        pose = im.cam_from_world()
        errs, rows = [], []
        for p in im.points2D:
            if p.has_point3D():
                pc = pose * rec.points3D[p.point3D_id].xyz
                uv = cam.img_from_cam(pc)
                errs.append(float(np.linalg.norm(np.asarray(uv) - np.asarray(p.xy))))
                rows.append((p.xy[0], p.xy[1], pc[2]))
        errors[im.name] = (float(np.mean(errs)) if errs else float("nan"), len(errs))
        obs[im.name] = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
        centres[im.name] = np.asarray(im.projection_center(), dtype=np.float64)
    return errors, obs, centres


def _depth_error(depth, alpha, rows: np.ndarray, scale: float, sx: float, sy: float) -> float:
    """Median |log(render depth / SfM depth)| at a photo's observed SfM points (opaque pixels)."""
    if not len(rows):
        return float("nan")
    h, w = depth.shape
    x = np.clip((rows[:, 0] * sx).astype(int), 0, w - 1)
    y = np.clip((rows[:, 1] * sy).astype(int), 0, h - 1)
    ok = (alpha[y, x] > 0.5) & (rows[:, 2] > 0)
    if not ok.any():
        return float("nan")
    return float(np.median(np.abs(np.log(depth[y, x][ok] / (scale * rows[ok, 2])))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfm", required=True, help="the sfm stage's folder (cameras.json, images/, points.npz)")
    ap.add_argument("--static", required=True, help="the static stage's folder (canonical.ply, metrics.json)")
    ap.add_argument("--out", default="heldout_diagnosis.png", help="contact sheet: render | photo | error | alpha")
    ap.add_argument("--threads", type=int, default=2, help="torch threads")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sfm = SfmOutputs(args.sfm)
    imgs, cams = load_inputs(sfm.path("images"), sfm.path("cameras"))
    metrics = json.loads((Path(args.static) / "metrics.json").read_text())
    held = set(metrics["holdout"])
    w, h = metrics["image_size"]
    g = load_ply(str(Path(args.static) / "canonical.ply"))
    reproj, obs, sfm_centres = _reprojection(Path(args.sfm) / "sparse" / "0")
    # the fit's frame is the SfM's scaled (and turned upright): the scale from the camera centres
    named = [c for c in cams if c.name in sfm_centres]
    pairs = [(a, b) for i, a in enumerate(named) for b in named[i + 1:]]
    scale = float(np.median([np.linalg.norm(a.center - b.center) / max(np.linalg.norm(sfm_centres[a.name] -
                                                                                     sfm_centres[b.name]), 1e-9)
                             for a, b in pairs]))
    train = [c for c in cams if c.name not in held]
    bg = torch.tensor([0.5, 0.5, 0.5])
    rows, sheet = [], []
    print("| photo | set | PSNR | after colour map | SH degree 0 | aligned (homography) | photo blurred (2 px) | "
          "depth error at SfM points | SfM reproj px (obs) | nearest train cam (units, deg) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for im, cam in zip(imgs, cams):
        c = cam.scaled(w, h)
        photo = F.interpolate(im.permute(2, 0, 1)[None].float(), size=(h, w), mode="area")[0].permute(1, 2, 0).numpy()
        with torch.no_grad():
            rgb, alpha, meta = rasterize(g.means, g.quats, g.log_scales.exp(), torch.sigmoid(g.opacity_logits), g.sh,
                                      c.torch_viewmat(), c.torch_K(), w, h, sh_degree=g.sh_degree, background=bg)
            rgb0, _, _ = rasterize(g.means, g.quats, g.log_scales.exp(), torch.sigmoid(g.opacity_logits),
                                   g.sh[:, :1].contiguous(), c.torch_viewmat(), c.torch_K(), w, h, sh_degree=0,
                                   background=bg)
        r, a = rgb.clamp(0, 1).numpy(), alpha.numpy()
        p_sh0 = _psnr(rgb0.clamp(0, 1).numpy(), photo)
        p_al = _aligned_psnr(r, photo)
        p_blur = _psnr(cv2.GaussianBlur(photo, (0, 0), 2.0), photo)
        dlog = _depth_error(meta["depth"].numpy(), a, obs.get(cam.name, np.zeros((0, 3))), scale, w / cam.width,
                            h / cam.height)
        mapped, _ = _affine(r, photo)
        opaque = a > 0.9
        p0, p1 = _psnr(r, photo), _psnr(mapped, photo)
        e, nobs = reproj.get(cam.name, (float("nan"), 0))
        dists = [(float(np.linalg.norm(t.center - cam.center)),
                  float(np.degrees(np.arccos(np.clip(np.dot(t.forward, cam.forward), -1, 1)))))
                 for t in train if t.name != cam.name]
        near = min(dists)
        kind = "held-out" if cam.name in held else "train"
        rows.append((cam.name, kind, p0, p1, p_sh0, p_al, p_blur, float(opaque.mean()), e, nobs, *near, dlog))
        print(f"| {cam.name} | {kind} | {p0:.2f} | {p1:.2f} | {p_sh0:.2f} | {p_al:.2f} | {p_blur:.2f} | "
              f"{100 * (np.exp(dlog) - 1):.0f}% | {e:.2f} ({nobs}) | {near[0]:.2f}, {near[1]:.0f} |", flush=True)
        if kind == "held-out":
            err = np.clip(np.abs(r - photo).mean(2, keepdims=True) * 3, 0, 1).repeat(3, 2)
            row = np.concatenate([r, photo, err, a[..., None].repeat(3, 2)], 1)
            row = (row * 255).round().astype(np.uint8)
            cv2.putText(row, f"{cam.name}: {p0:.1f} dB, colour-mapped {p1:.1f} dB", (8, 24), cv2.FONT_HERSHEY_SIMPLEX,
                        0.7, (255, 255, 0), 2)
            sheet.append(row)
    for kind in ("train", "held-out"):
        sel = [r for r in rows if r[1] == kind]
        if sel:
            mean = lambda i: float(np.nanmean([r[i] for r in sel]))
            print(f"\n{kind}: mean PSNR {mean(2):.2f}, after colour map {mean(3):.2f}, SH degree 0 {mean(4):.2f}, "
                  f"aligned {mean(5):.2f}, photo blurred {mean(6):.2f}, SfM reprojection {mean(8):.2f} px, "
                  f"{mean(9):.0f} obs, nearest train camera {mean(10):.2f} units, median depth error at SfM points "
                  f"{100 * (np.exp(mean(12)) - 1):.0f}%")
    if sheet:
        cv2.imwrite(args.out, cv2.cvtColor(np.concatenate(sheet, 0), cv2.COLOR_RGB2BGR))
        print(f"\ncontact sheet: {args.out} (render | photo | |error| x3 | alpha)")


if __name__ == "__main__":
    main()
