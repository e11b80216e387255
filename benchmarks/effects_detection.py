"""Effects detection on a finished synthetic run, scored against its ground truth.

    python benchmarks/effects_detection.py results/demo /tmp/effects_eval ['{"flower_max_behind": 0.2}']

Runs :func:`anigs.effects.detect_effects` on the run's undistorted photos, SfM cameras and fitted
model with the run's effects config (``effects/effects.json``, overridden by the optional JSON),
writes ``regions.npy`` and ``overview.png`` to OUT_DIR and prints, per region, the pixel
precision / recall / IoU against the ground-truth label maps rendered through the camera alignment,
and the Gaussian precision / recall against the appearance labels of the fitted Gaussians (what
the fitted model shows), with what the predicted Gaussians really are.
"""
import sys, time, json, logging  # noqa: E401
from pathlib import Path
import numpy as np, torch
torch.set_num_threads(1)
logging.basicConfig(level=logging.INFO, format="%(message)s")
from anigs.cameras import load_cameras
from anigs.gaussians import load_ply
from anigs.images import find_image, load_image
from anigs.effects import detect_effects, Config, save_overview, REGIONS
from anigs.render.labels import appearance_labels, render_label_map
from anigs.sfm.align import align_cameras

root, out = Path(sys.argv[1]), Path(sys.argv[2]); out.mkdir(parents=True, exist_ok=True)
over = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
cfgd = json.load(open(root / "effects/effects.json"))["config"] if (root / "effects/effects.json").exists() else {}
cfgd.update(over)
cfg = Config.from_dict(cfgd)
g = load_ply(root / "static/canonical.ply")
cams = load_cameras(root / "sfm/cameras.json")
imgs = [load_image(find_image(root / "sfm/images", c.name)) for c in cams]
t = time.time()
res = detect_effects(imgs, cams, g, cfg)
print(f"detect {time.time()-t:.1f}s; detected {res.detected}; ground {res.ground.to_dict()}")
res.save(out); save_overview(out / "overview.png", res)
for e, r in res.effects.items():
    print(f"  {e:13s} det={r.detected} pf={r.pixel_fraction:.4f} gf={r.gaussian_fraction:.4f} n={len(r.indices)} photos={r.photo_fraction:.2f} conf={r.confidence:.2f}")
gt = root / "capture/gt"
if gt.exists():
    labels = np.load(gt / "labels.npy"); names = json.load(open(gt / "motion.json"))["labels"]
    ids = {v: int(k) for k, v in names.items()}
    gg = load_ply(gt / "gaussians.ply")
    sim, rms = align_cameras(cams, load_cameras(gt / "cameras.json"))
    cache = out / "appearance_labels.npy"  # the slow part: kept for re-runs into the same OUT_DIR
    if cache.exists():
        app = np.load(cache)
    else:
        app, _, _ = appearance_labels(g, gg, labels, cams, to_labels_frame=sim); np.save(cache, app)
    print(f"align rms {rms:.4f}; appearance label counts", {names[str(k)] if k >= 0 else 'sky': int(v) for k, v in zip(*np.unique(app, return_counts=True))})
    stats = {}
    lmaps = [render_label_map(gg, labels, sim.apply_camera(c)) for c in res.cameras]
    for k, reg in enumerate(REGIONS):
        if reg not in ids:
            continue
        truth = app == ids[reg]; pred = res.region_of == k
        tp = (truth & pred).sum()
        gP, gR = tp / max(pred.sum(), 1), tp / max(truth.sum(), 1)
        eff = {"foliage": "foliage_sway", "grass": "grass_wave", "flowers": "flower_bob", "water": "water_ripple"}[reg]
        I = P = T = 0
        for lm, m in zip(lmaps, res.effects[eff].masks):
            tm = lm == ids[reg]; I += (tm & m).sum(); P += m.sum(); T += tm.sum()
        pP, pR = I / max(P, 1), I / max(T, 1)
        # what the predicted Gaussians really are
        conf = {names[str(x)] if x >= 0 else "sky": int(c) for x, c in zip(*np.unique(app[pred], return_counts=True))}
        print(f"  {reg:8s} pixel P={pP:.3f} R={pR:.3f} IoU={I/max(P+T-I,1):.3f} (true px share {T/sum(l.size for l in lmaps):.4f}) | "
              f"gauss P={gP:.3f} R={gR:.3f} (true {truth.sum()}, pred {pred.sum()}) pred is {conf}")
