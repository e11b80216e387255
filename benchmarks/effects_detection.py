"""Effects detection on a finished synthetic run, scored against its ground truth.

    python benchmarks/effects_detection.py results/demo /tmp/effects_eval ['{"regions": {"flower_max_behind": 0.2}}']

Runs :func:`anigs.effects.detect_effects` on the run's undistorted photos, SfM cameras and fitted
model with the run's effects config (the effects stage's report, overridden by the optional JSON),
writes the detection report, the regions and the overview into OUT_DIR (laid out as the effects stage's folder) and prints, per region, the pixel
precision / recall / IoU against the ground-truth label maps rendered through the camera alignment,
and the Gaussian precision / recall against the appearance labels of the fitted Gaussians (what
the fitted model shows), with what the predicted Gaussians really are.
"""
import sys, time, json, logging  # noqa: E401
from pathlib import Path
import numpy as np, torch
torch.set_num_threads(1)
logging.basicConfig(level=logging.INFO, format="%(message)s")
from anigs.images import find_image, load_image
from anigs.effects import detect_effects, EffectsConfig, save_overview, REGIONS
from anigs.io import write_json
from anigs.sfm.align import align_cameras
from anigs.render.labels import appearance_labels, render_label_map
from anigs.stages import capture, effects, sfm, static

root, out = Path(sys.argv[1]), effects.Outputs(sys.argv[2]); out.root.mkdir(parents=True, exist_ok=True)
over = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
run_effects = effects.Outputs(root / "effects")
cfgd = run_effects.report()["config"] if run_effects.exists("effects") else {}
cfgd.update(over)
cfg = EffectsConfig.from_dict(cfgd)
g = static.Outputs(root / "static").canonical()
run_sfm = sfm.Outputs(root / "sfm")
cams = run_sfm.cameras()
imgs = [load_image(find_image(run_sfm.path("images"), c.name)) for c in cams]
t = time.time()
res = detect_effects(imgs, cams, g, cfg)
print(f"detect {time.time()-t:.1f}s; detected {res.detected}; ground {res.ground.to_dict()}")
write_json(out.path("effects"), res.to_json()); np.save(out.path("regions"), res.region_of.astype(np.int8))
save_overview(out.path("overview"), res)
for e, r in res.effects.items():
    print(f"  {e:13s} det={r.detected} pf={r.pixel_fraction:.4f} gf={r.gaussian_fraction:.4f} n={len(r.indices)} photos={r.photo_fraction:.2f} conf={r.confidence:.2f}")
gt = capture.Outputs(root / "capture")
if gt.is_synthetic():
    labels = gt.gt_labels(); names = gt.gt_motion()["labels"]
    ids = {v: int(k) for k, v in names.items()}
    gg = gt.gt_gaussians()
    sim, rms = align_cameras(cams, gt.gt_cameras())
    cache = out.root / "appearance_labels.npy"  # the slow part: kept for re-runs into the same OUT_DIR
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
