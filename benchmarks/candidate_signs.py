"""What the effects stage's plant candidates look like to weight-free tests: one row per candidate of a cached fit.

    python benchmarks/candidate_signs.py --cache CACHE --seeds 0 3 --capture courtyard-p30 lund-street \
        [--prompt "..."] [--json OUT]

For each capture and fit seed (``CACHE/seed-K/<capture>``, the fits of ``benchmarks/real_captures.py --seeds``)
the effects stage runs with the capture's first phrasing that names what moves (or ``--prompt``), and every
numbered foliage, grass or flower candidate gets a row: its Gaussians, the rule that decided it (blank: kept),
where it lands on the hand-made labels (pixels on must-move and must-stay-still marks in the labelled photos,
rendered from their cameras) and the signs a rule could read without weights (medians over its Gaussians, or over
the analysed photos that show it on at least 20 px):

- ``texture``: the photos' luminance gradient inside its footprint, relative to the local brightness (leaves are
  said to be textured, paint smooth);
- ``spread``: the relative spread of the photos' luminance at its Gaussians' centres over the photos that see
  them (:func:`anigs.effects.geometry.colour_spread`: "photos from different sides see different leaves");
- ``sfm_obs``: SfM observations per 1000 photo pixels inside its footprint (leaves give many keypoints);
- ``depth_flat``: the rendered depth inside its footprint lifted to 3D, thinness of that cloud (0 on one plane);
- ``along_rays``: |cos| between each Gaussian's longest axis and its ray from the photo (needles along the view);
- the rules' own figures (``smooth``, ``turning`` of ``made_surface``; ``on_plane`` of ``plane``).

The table says whether a sign separates the made things a capture's labels name (the courtyard's green bin) from
the plants (the street's shrubs, the flower's leaves); the note of issue 47 quotes it.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from real.labels import load_labels  # noqa: E402

MIN_PIXELS = 20  # a photo shows a candidate where it carries the render on this many pixels
LUMA = np.array([0.299, 0.587, 0.114], np.float32)
PLANTS = ("foliage", "grass", "flowers")


def texture(img: np.ndarray, own: np.ndarray) -> float:
    """Median relative gradient |grad L| / (local mean L + 0.05) over ``own`` [H,W] of photo ``img`` [H,W,3]."""
    lum = (img @ LUMA).astype(np.float32)
    grad = np.hypot(cv2.Sobel(lum, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(lum, cv2.CV_32F, 0, 1, ksize=3)) / 8
    rel = grad / (cv2.blur(lum, (5, 5)) + 0.05)
    inner = cv2.erode(own.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return float(np.median(rel[inner if inner.sum() >= 10 else own]))


def depth_flatness(depth: np.ndarray, own: np.ndarray, cam) -> float:
    """sqrt(l0 / l1) of the 3D points the rendered ``depth`` gives inside ``own`` (0: one plane)."""
    ys, xs = np.nonzero(own)
    k = cam.torch_K().double().numpy()
    z = depth[ys, xs].astype(np.float64)
    pts = np.stack([(xs + 0.5 - k[0, 2]) / k[0, 0] * z, (ys + 0.5 - k[1, 2]) / k[1, 1] * z, z], 1)
    ev = np.linalg.eigvalsh(np.cov((pts - pts.mean(0)).T))
    return float(np.sqrt(max(ev[0], 0.0) / max(ev[1], 1e-18)))


def sfm_density(rows: np.ndarray, own: np.ndarray, full) -> tuple[int, float]:
    """(pixels, SfM observations per 1000 pixels of the photo as captured) inside ``own`` (the analysed size);
    ``rows`` [M,3] the photo's tracks (x, y, depth) in ``full``'s pixels."""
    h, w = own.shape
    sx, sy = w / full.width, h / full.height
    x, y = np.floor(rows[:, 0] * sx).astype(int), np.floor(rows[:, 1] * sy).astype(int)
    ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    inside = int(own[y[ok], x[ok]].sum())
    return int(own.sum()), 1000.0 * inside * sx * sy / max(int(own.sum()), 1)


class Staged:
    """The effects stage's inner records of one run (the Gaussians, the cues, the rules' outcome)."""

    def __init__(self) -> None:
        import anigs.effects.detect as detect

        self.record: dict = {}
        self._orig = detect.apply_rules

        def wrapped(g, cues, region_of, regions, cfg, blossoms_of=None):
            out = self._orig(g, cues, region_of, regions, cfg, blossoms_of)
            self.record.update(g=g, cues=cues, ruled=out)
            return out

        detect.apply_rules = wrapped


def signs(g, cues, cand, spread: np.ndarray, tracks: dict, full: dict) -> dict:
    """The signs of the module docstring for one candidate."""
    from anigs.effects.geometry import SHOWN, render_features
    from anigs.geometry.quaternion import quat_to_rotmat

    ind = np.zeros((g.num, 1), np.float32)
    ind[cand.indices] = 1.0
    idx = cand.indices
    scales = g.scales[idx].double().numpy()
    axes = quat_to_rotmat(g.quats[idx]).double().numpy()[np.arange(len(idx)), :, scales.argmax(1)]
    means = g.means[idx].double().numpy()
    tex, flat, cos, dens = [], [], [], []
    for p in cues.maps:
        f, a, _ = render_features(g, ind, p.camera)
        own = (f[..., 0] >= SHOWN) & (a >= SHOWN)
        if own.sum() < MIN_PIXELS:
            continue
        tex.append(texture(p.image, own))
        flat.append(depth_flatness(p.depth, own, p.camera))
        ray = means - np.asarray(p.camera.center)[None]
        cos.append(np.abs((axes * ray).sum(1)) / np.linalg.norm(ray, axis=1))
        stem = Path(p.camera.name).stem
        if stem in tracks:
            dens.append(sfm_density(tracks[stem], own, full[stem]))
    med = (lambda v: float(np.median(v)) if len(v) else float("nan"))
    return {"photos": len(tex), "texture": med(tex), "spread": float(np.median(spread[idx])),
            "sfm_obs": sum(n * d for n, d in dens) / max(sum(n for n, _ in dens), 1) if dens else float("nan"),
            "depth_flat": med(flat), "along_rays": med(np.concatenate(cos)) if cos else float("nan"),
            **{k: float(v) for k, v in cand.figures.items() if k in ("smooth", "turning", "on_plane")}}


def on_labels(g, cand, labels, cams: dict, sizes: dict) -> tuple[int, int]:
    """Pixels where ``cand`` moves the render as the benchmark scores it (:func:`real_captures.moving_of`) on the
    must-move and must-stay-still marks; ``sizes``: the labelled photos' sizes (:func:`real_captures.photo_sizes`)."""
    import real_captures as rc

    own = np.zeros(g.num, bool)
    own[cand.indices] = True
    moving = rc.moving_of(g, own, np.zeros(g.num, np.int64), cams, [pl.name for pl in labels.photos])
    move = still = 0
    for pl in labels.photos:
        if pl.name not in moving:
            continue
        m = moving[pl.name] > 0
        mv, st = pl.masks(m.shape[0], m.shape[1], sizes[pl.name])
        move += int((m & mv).sum())
        still += int((m & st).sum())
    return move, still


def run(cache: Path, capture: str, prompt: str, captures: Path, staged: Staged) -> list[dict]:
    """Every plant candidate of the effects stage on ``cache/<capture>`` with ``prompt``, with its signs."""
    from anigs.cameras import load_cameras
    from anigs.effects.config import EffectsConfig
    from anigs.effects.geometry import colour_spread
    from anigs.sfm.tracks import load_tracks
    from anigs.stages import effects as stage
    from anigs.stages.static import Outputs as StaticOutputs

    scene = cache / capture
    out = stage.Outputs(scene / "candidate_signs")
    stage.run(stage.Inputs(canonical=scene / "static" / "canonical.ply", cameras=scene / "sfm" / "cameras.json",
                           images=scene / "sfm" / "images", out=out, prompt=prompt,
                           static=StaticOutputs(scene / "static")),
              EffectsConfig.from_dict({"prompt": prompt, "requested": "auto"}))
    g, cues, ruled = staged.record["g"], staged.record["cues"], staged.record["ruled"]
    spread = colour_spread(g, [p.image for p in cues.maps], [p.camera for p in cues.maps], [p.depth for p in cues.maps])
    full = {Path(c.name).stem: c for c in load_cameras(scene / "sfm" / "cameras.json")}
    tracks = {Path(k).stem: v for k, v in load_tracks(scene / "sfm" / "tracks.npz").items()}
    import real_captures as rc

    labels = load_labels(capture)
    sizes = rc.photo_sizes(captures, capture, labels)  # read once, not per candidate
    rows = []
    for c in ruled.candidates:
        if c.region not in PLANTS:
            continue
        move, still = on_labels(g, c, labels, full, sizes)
        rows.append({"capture": capture, "number": c.number, "region": c.region, "gaussians": len(c.indices),
                     "rule": c.rule if (not c.kept or c.moved_to) else "", "moved_to": c.moved_to,
                     "on_move_px": move, "on_still_px": still, **signs(g, cues, c, spread, tracks, full)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--captures", type=Path, default=ROOT.parent / "shared" / "captures")
    ap.add_argument("--capture", nargs="+", required=True)
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--prompt", default=None, help="default: the capture's first phrasing that names what moves")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    import real_captures as rc

    staged = Staged()
    cols = ("texture", "spread", "sfm_obs", "depth_flat", "along_rays", "smooth", "on_plane")
    print("| capture | seed | # | region | Gaussians | rule | on move / still px | " + " | ".join(cols) + " |")
    print("|---|---|---|---|---|---|---|" + "---|" * len(cols))
    rows = []
    for capture in a.capture:
        phr = rc.phrasings(capture)
        prompt = a.prompt or next((p["prompt"] for p in phr if p["kind"] == "plain"), phr[0]["prompt"])
        for seed in a.seeds:
            for r in run(a.cache / f"seed-{seed}", capture, prompt, a.captures, staged):
                r["seed"] = seed
                rows.append(r)
                vals = " | ".join(f"{r.get(k, float('nan')):.3f}" for k in cols)
                print(f"| {capture} | {seed} | {r['number']} | {r['region']}{'->' + r['moved_to'] if r['moved_to'] else ''}"
                      f" | {r['gaussians']} | {r['rule'] or 'kept'} | {r['on_move_px']} / {r['on_still_px']} | {vals} |",
                      flush=True)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
