"""Where the demo's ground-truth motion figures come from, and how much they move by chance.

For each results folder of a synthetic scene (``RESULTS/SCENE``, variant ``full``) this prints the
eval's GT amplitude / frequency W1 (recomputed from the final model, as ``anigs eval`` does), a
bootstrap spread of both over the learned moving Gaussians (resampled with replacement, the
ground truth fixed: the figure's sampling noise for one model), and a breakdown by ground-truth
label (each learned dynamic Gaussian takes the label of the nearest ground-truth Gaussian after the
camera alignment, as ``gt/moving_labelled_still`` does): how many dynamic Gaussians, their
median amplitude and frequency, and each label's share of the learned set. Two runs that differ by
more than the bootstrap spread differ in the model, not in sampling; whether that is a real loss
needs runs that differ only by chance (another seed).

    python benchmarks/motion_spread.py /work/wt/base/results/demo results/noreg/demo [--boot 200]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.eval import Outputs as EvalOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.update import Outputs as UpdateOutputs


def _final_model(scene_dir: Path, variant: str) -> Path:
    rounds = sorted((UpdateOutputs(d) for d in (scene_dir / variant).glob("round*") if UpdateOutputs(d).exists("model")),
                    key=lambda o: int(o.root.name[5:]))
    if not rounds:
        raise SystemExit(f"{scene_dir / variant}: no round*/{UpdateOutputs.LAYOUT['model'].name}")
    return rounds[-1].path("model")


def analyse(scene_dir: Path, variant: str, boot: int, seed: int) -> dict:
    import torch
    from scipy.spatial import cKDTree
    from scipy.stats import wasserstein_distance

    from anigs.animate.deform import load_model
    from anigs.geometry.extent import scene_extent
    from anigs.sfm.align import align_cameras
    from anigs.metrics.motion import trajectory_stats
    from anigs.synth.motion import MotionParams, gt_clip_offsets

    results, scene = scene_dir.parent, scene_dir.name
    capture = CaptureOutputs.at(results, scene=scene)
    canon, deformation, _ = load_model(_final_model(scene_dir, variant),
                                       StaticOutputs.at(results, scene=scene).path("canonical"))
    T = deformation.num_frames
    with torch.no_grad():
        learned = deformation.trajectories(canon.means, torch.arange(T)).permute(1, 0, 2).double().numpy()
    dyn_idx = deformation.dynamic_index.numpy()
    gt_g = capture.gt_gaussians()
    labels = capture.gt_labels()
    params = MotionParams.from_dict(capture.gt_motion()["params"])
    names = {int(k): v for k, v in capture.gt_motion()["labels"].items()}
    off = gt_clip_offsets(params, gt_g.means, torch.as_tensor(capture.gt_anchors()),
                          torch.as_tensor(labels).long())
    moving = (off.abs().amax(dim=(0, 2)) > 0).numpy()
    gt_traj = (gt_g.means[moving][None] + off[:, moving]).permute(1, 0, 2).double().numpy()
    cams = SfmOutputs.at(results, scene=scene).cameras()
    gt_cams = capture.gt_cameras()
    a_l, f_l = trajectory_stats(learned, scene_extent(cams))
    a_g, f_g = trajectory_stats(gt_traj, scene_extent(gt_cams))
    f_g = f_g[np.isfinite(f_g)]
    ok = np.isfinite(f_l)
    out = {"dynamic": int(len(a_l)), "gaussians": int(canon.num),
           "amplitude_w1": float(wasserstein_distance(a_l, a_g)),
           "frequency_w1": float(wasserstein_distance(f_l[ok], f_g)),
           "rms_amplitude_ratio": float(np.sqrt(np.mean(a_l ** 2)) / np.sqrt(np.mean(a_g ** 2)))}
    rng = np.random.default_rng(seed)
    ab, fb = [], []
    for _ in range(boot):
        i = rng.integers(0, len(a_l), len(a_l))
        ab.append(wasserstein_distance(a_l[i], a_g))
        fi = f_l[i]
        fb.append(wasserstein_distance(fi[np.isfinite(fi)], f_g))
    out["amplitude_w1_boot_sd"] = float(np.std(ab))
    out["frequency_w1_boot_sd"] = float(np.std(fb))
    # per ground-truth label of the learned dynamic Gaussians
    sim, _ = align_cameras(cams, gt_cams)
    pts = sim.apply(canon.means.detach().double().numpy()[dyn_idx])
    _, nn = cKDTree(gt_g.means.detach().double().numpy()).query(pts, k=1)
    lab = labels[nn]
    by = {}
    for k in np.unique(lab):
        m = lab == k
        by[names.get(int(k), str(k))] = {"n": int(m.sum()), "amp_median": float(np.median(a_l[m])),
                                         "freq_median": float(np.nanmedian(f_l[m]))}
    gl = labels[moving]
    a_gt_all, f_gt_all = trajectory_stats(gt_traj, scene_extent(gt_cams))
    for k in np.unique(gl):
        m = gl == k
        name = names.get(int(k), str(k))
        by.setdefault(name, {"n": 0})
        by[name].update({"gt_n": int(m.sum()), "gt_amp_median": float(np.median(a_gt_all[m])),
                         "gt_freq_median": float(np.nanmedian(f_gt_all[m]))})
    out["by_label"] = by
    metrics = EvalOutputs.at(results, scene=scene, variant=variant).path("metrics")
    if metrics.exists():
        m = json.loads(metrics.read_text()).get("metrics", {})
        out["eval"] = {k: m.get(k, {}).get("value") for k in ("gt/amplitude_w1", "gt/frequency_w1", "multiview/psnr_novel")}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path, help="results/SCENE folders of a synthetic scene")
    ap.add_argument("--variant", default="full")
    ap.add_argument("--boot", type=int, default=200, help="bootstrap resamples of the learned Gaussians")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    for s in args.scenes:
        r = analyse(s, args.variant, args.boot, args.seed)
        print(f"== {s}: {r['dynamic']} dynamic of {r['gaussians']} Gaussians; eval {r.get('eval')}")
        print(f"   amplitude W1 {r['amplitude_w1']:.6f} (bootstrap sd {r['amplitude_w1_boot_sd']:.6f}), "
              f"frequency W1 {r['frequency_w1']:.5f} (sd {r['frequency_w1_boot_sd']:.5f}), "
              f"RMS amplitude ratio {r['rms_amplitude_ratio']:.3f}")
        for name, b in sorted(r["by_label"].items()):
            print(f"   {name:>14}: learned {b['n']:5d} amp {b.get('amp_median', float('nan')):.5f} "
                  f"freq {b.get('freq_median', float('nan')):.3f} | GT {b.get('gt_n', 0):5d} "
                  f"amp {b.get('gt_amp_median', float('nan')):.5f} freq {b.get('gt_freq_median', float('nan')):.3f}")


if __name__ == "__main__":
    main()
