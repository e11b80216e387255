"""Per-effect DCT capacity (``update.effect_num_bases``) on a finished demo run: does giving the
slow effects fewer bases than the flutter pay?

    source .venv/bin/activate
    python benchmarks/effect_capacity.py --demo /tmp/t0/results/demo --out /tmp/capC/bench --threads 1 \\
        [--variants K12,sway4_grass6_flower6,tight] [--identity-tree /tmp/capC/base] [--no-eval] [--seed-delta 1]

Re-runs only the final round's update of ``--demo`` (``{variant_dir}/round{R}``: the init model,
targets and seed recorded in its ``model.pt`` / ``update.json``, ``--masks`` containment as the
workflow runs it), once per capacity variant, then ``anigs final``, ``anigs eval`` (the recorded eval
config; ``multiview_capture`` off: it does not depend on the model) and ``anigs export`` on each.
The K12 variant is every Gaussian at num_bases (``effect_num_bases: {}``); the others need per-Gaussian
effect labels. The workflow's own are the masks stage's effect labels (from the effects
stage's regions); this script uses ideal ones, the ground-truth labels of
``capture/gt`` moved onto the dynamic Gaussians (nearest moving ground-truth Gaussian, after the
camera alignment the masks stage uses), 1 + region index (foliage 1, grass 2, flowers 3).

Prints one table: update wall / CPU seconds (with the load average), model and export sizes, the
eval's GT motion metrics and static leakage, and per effect (region) the GT motion distances
(:func:`anigs.metrics.motion.gt_motion_distances` on that region's Gaussians) and the share of the
learned displacement power above the region's ground-truth band (``hf``; the ground truth's own
share in brackets). With ``--identity-tree`` (a copy of the package before the key existed) the
K12 update also runs on that code and the two ``model.pt`` files are compared byte for byte.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from anigs.stages import capture as capture_stage, masks as masks_stage, sfm as sfm_stage, static as static_stage
from anigs.stages.eval import Outputs as EvalOutputs
from anigs.stages.final import Outputs as FinalOutputs
from anigs.stages.update import Outputs as UpdateOutputs

VARIANTS: dict[str, dict] = {
    "K12": {},  # today: every dynamic Gaussian uses num_bases = 12
    # slow sway needs few bases, but foliage also flutters (5 cycles = k 10): foliage keeps 12
    "sway4_grass6_flower6": {"foliage_sway": 4, "leaf_flutter": 12, "grass_wave": 6, "flower_bob": 6},
    # the ground truth's bands: c cycles per clip is DCT k = 2c (sway 1, flutter 5, grass 2, flowers 2)
    "tight": {"foliage_sway": 2, "leaf_flutter": 10, "grass_wave": 4, "flower_bob": 4},
}
REGION_GT_CYCLES = {"foliage": 5, "grass": 2, "flowers": 2}  # highest ground-truth cycles per clip


def _run(cmd: list[str], log: Path, env: dict | None = None) -> dict:
    """Run ``cmd`` (output to ``log``); wall and child CPU seconds, load average before."""
    load = os.getloadavg()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        rc = subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env, check=False).returncode
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if rc != 0:
        sys.exit(f"failed ({rc}): {' '.join(cmd)}\n{log.read_text()[-3000:]}")
    return {"wall_s": round(wall, 2), "cpu_s": round((r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), 2),
            "load": [round(x, 2) for x in load]}


def _anigs(threads: int) -> list[str]:
    return [sys.executable, "-c", "import sys; from anigs.cli import main; sys.exit(main())", "--threads", str(threads)]


def effect_labels_for_demo(demo: Path, out: Path) -> Path:
    """Int dynamic mask [N] (0 static, 1 + region index) of the demo's dynamic set from the GT labels."""
    from anigs.effects.config import REGIONS
    from anigs.sfm.align import align_cameras
    from anigs.render.labels import transfer_labels

    dyn = masks_stage.Outputs(demo / "masks").dynamic()
    gt = capture_stage.Outputs(demo / "capture")
    motion = gt.gt_motion()
    gt_labels = gt.gt_labels()
    region_of_gt = {int(i): (1 + REGIONS.index(n) if n in REGIONS else 0) for i, n in motion["labels"].items()}
    gt_lab = np.array([region_of_gt[int(x)] for x in gt_labels])
    sim, _ = align_cameras(gt.gt_cameras(), sfm_stage.Outputs(demo / "sfm").cameras())
    gt_means = sim.apply(gt.gt_gaussians().means.detach().double().numpy())
    means = static_stage.Outputs(demo / "static").canonical().means.detach().double().numpy()
    moving = gt_lab > 0
    labels = np.zeros(len(dyn), np.int64)
    labels[dyn] = transfer_labels(gt_means[moving], gt_lab[moving], means[dyn])
    path = out / "dynamic_labels.npy"
    np.save(path, labels)
    return path


def masks_folder(demo: Path, out: Path, labels: Path | None) -> Path:
    """The demo's masks folder as the update reads it, with ``labels`` (int [N]) as its effect labels, or
    with none (links to the demo's files)."""
    from anigs.stages.masks import Outputs as MasksOutputs

    src, dst = MasksOutputs(demo / "masks"), MasksOutputs(out)
    out.mkdir(parents=True, exist_ok=True)
    for p in src.root.iterdir():
        if p.name != src.path("effect_labels").name and not (out / p.name).exists():
            (out / p.name).symlink_to(p.resolve())
    dst.path("effect_labels").unlink(missing_ok=True)
    if labels is not None:
        np.save(dst.path("effect_labels"), np.load(labels).astype(np.int8))
    return out


def per_effect(model: Path, canonical: Path, labels: np.ndarray, demo: Path) -> dict[str, dict]:
    """GT motion distances and above-band power share per region (foliage, grass, flowers)."""
    import torch

    from anigs.animate.deform import load_model
    from anigs.effects.config import REGIONS
    from anigs.geometry.extent import scene_extent
    from anigs.metrics.motion import gt_motion_distances
    from anigs.synth.motion import MotionParams, gt_clip_offsets

    canon, d, _ = load_model(model, canonical)
    T = d.num_frames
    with torch.no_grad():
        learned = d.trajectories(canon.means, torch.arange(T)).permute(1, 0, 2).double().numpy()  # [D,T,3]
    lab_l = labels[d.dynamic_index.numpy()]
    gt = capture_stage.Outputs(demo / "capture")
    motion = gt.gt_motion()
    gt_g = gt.gt_gaussians()
    gt_labels = gt.gt_labels()
    params = MotionParams.from_dict(motion["params"])
    off = gt_clip_offsets(params, gt_g.means, torch.as_tensor(gt.gt_anchors()),
                          torch.as_tensor(gt_labels).long())
    moving = (off.abs().amax(dim=(0, 2)) > 0).numpy()
    gt_traj = (gt_g.means[None] + off).permute(1, 0, 2).double().numpy()  # [M,T',3]
    ext_l = scene_extent(sfm_stage.Outputs(demo / "sfm").cameras())
    ext_g = scene_extent(gt.gt_cameras())
    name_of = {int(i): n for i, n in motion["labels"].items()}
    out = {}
    for region, cycles in REGION_GT_CYCLES.items():
        sel_l = lab_l == 1 + REGIONS.index(region)
        sel_g = moving & np.array([name_of[int(x)] == region for x in gt_labels])
        if not sel_l.any() or not sel_g.any():
            continue
        r = gt_motion_distances(learned[sel_l], gt_traj[sel_g], ext_l, ext_g)
        r["hf"] = _above_band(learned[sel_l], cycles)
        r["hf_gt"] = _above_band(gt_traj[sel_g], cycles)
        k = d.active_bases[torch.from_numpy(sel_l)] if d.active_bases is not None else None
        r["K"] = int(k.max()) if k is not None else d.num_bases
        out[region] = r
    return out


def _above_band(traj: np.ndarray, cycles: int) -> float:
    """Share of displacement power [N,T,3] above ``cycles`` + 1/2 cycles per clip (DC excluded)."""
    x = traj - traj.mean(axis=1, keepdims=True)
    p = (np.abs(np.fft.rfft(x, axis=1)) ** 2).sum(axis=(0, 2))  # [T//2+1], bin = cycles per clip
    total = p[1:].sum()
    return float(p[cycles + 1:].sum() / total) if total > 0 else float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", type=Path, default=Path("/tmp/t0/results/demo"))
    ap.add_argument("--variant-dir", default="full")
    ap.add_argument("--out", type=Path, default=Path("/tmp/capC/bench"))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--identity-tree", type=Path, default=None,
                    help="a copy of the package before effect_num_bases: its K12 model must be byte-identical")
    ap.add_argument("--no-eval", action="store_true", help="skip final + eval (the per-effect GT metrics remain)")
    ap.add_argument("--seed-delta", type=int, default=0, help="add this to the recorded update seed (seed noise)")
    a = ap.parse_args()
    import torch

    demo, out = a.demo, a.out
    out.mkdir(parents=True, exist_ok=True)
    vdir = demo / a.variant_dir
    R = max(int(p.name[5:]) for p in vdir.glob("round*") if UpdateOutputs(p).exists("model"))
    demo_round = UpdateOutputs(vdir / f"round{R}")
    ref = torch.load(demo_round.path("model"), map_location="cpu", weights_only=True)
    upd = demo_round.json("log")
    base_cfg = dict(upd["config"], seed=upd["config"]["seed"] + a.seed_delta)
    labels_path = effect_labels_for_demo(demo, out)
    labels = np.load(labels_path)
    canonical = static_stage.Outputs(demo / "static").path("canonical")
    rows = {}
    for name in a.variants.split(","):
        v_out = out / name
        (v_out / "logs").mkdir(parents=True, exist_ok=True)
        cfg = dict(base_cfg, effect_num_bases=VARIANTS[name])
        rd = UpdateOutputs(v_out / f"round{R}")
        model = rd.path("model")
        model.parent.mkdir(exist_ok=True)
        masks = masks_folder(demo, out / ("masks_labelled" if VARIANTS[name] else "masks_plain"),
                             labels_path if VARIANTS[name] else None)
        init = Path(ref["extra"]["init_model"]).parent
        upd_args = ["update", "--static", str(demo / "static"), "--init", str(init), "--targets", *ref["extra"]["targets"],
                    "--views", str(demo / "views"), "--masks", str(masks), "--out", str(rd.root),
                    "--params", json.dumps(cfg, sort_keys=True)]
        row = {"update": _run(_anigs(a.threads) + upd_args, v_out / "logs" / "update.log")}
        info = rd.json("log")
        row["train_s"] = round(info["seconds"], 2)
        row["contain_s"] = info.get("containment", {}).get("seconds")
        row["dynamic_after"] = info.get("containment", {}).get("dynamic_after", info["num_dynamic"])
        row["model_bytes"] = model.stat().st_size
        row["same_bytes_as_demo"] = model.read_bytes() == demo_round.path("model").read_bytes()
        if name == "K12" and a.identity_tree is not None:
            old = UpdateOutputs(v_out / "identity")
            env = dict(os.environ, PYTHONPATH=str(a.identity_tree))
            args = [x if x != str(rd.root) else str(old.root) for x in upd_args]
            row["identity_update"] = _run(_anigs(a.threads) + args, v_out / "logs" / "identity.log", env)
            row["identical_to_before"] = old.path("model").read_bytes() == model.read_bytes()
        exp = v_out / "export"
        row["export"] = _run(_anigs(a.threads) + ["export", "--static", str(demo / "static"), "--model", str(rd.root),
                                                   "--out", str(exp), "--params", "{}"], v_out / "logs" / "export.log")
        row["export_bytes"] = {p.name: p.stat().st_size for p in sorted(exp.iterdir()) if p.is_file()}
        if not a.no_eval:
            fin = FinalOutputs(vdir / "final").json("summary")["config"]
            row["final"] = _run(_anigs(a.threads) + [
                "final", "--static", str(demo / "static"), "--model", str(rd.root), "--views", str(demo / "views"),
                "--sfm", str(demo / "sfm"), "--masks", str(demo / "masks"), "--out", str(v_out / "final"),
                "--params", json.dumps(fin)], v_out / "logs" / "final.log")
            ev = EvalOutputs(vdir / "eval").record()["config"]
            ev["multiview_capture"] = False
            row["eval"] = _run(_anigs(a.threads) + [
                "eval", "--final", str(v_out / "final"), "--masks", str(demo / "masks"), "--model", str(rd.root),
                "--static", str(demo / "static"), "--sfm", str(demo / "sfm"), "--capture", str(demo / "capture"),
                "--scene", "demo", "--method", "Ours", "--variant", name,
                "--out", str(v_out / "eval"), "--params", json.dumps(ev)], v_out / "logs" / "eval.log")
            m = EvalOutputs(v_out / "eval").record()["metrics"]
            row["metrics"] = {k: m[k]["value"] for k in m}
        row["effects"] = per_effect(model, canonical, labels, demo)
        rows[name] = row
        (out / "results.json").write_text(json.dumps(rows, indent=1))
    _print(rows, R, a.threads, base_cfg["seed"])
    return 0


def _print(rows: dict, R: int, threads: int, seed: int) -> None:
    names = list(rows)
    w = max(14, *(len(n) + 2 for n in names))
    line = lambda label, vals: print(f"{label:<34}" + "".join(f"{v:>{w}}" for v in vals))
    print(f"\nround {R} update per variant (--threads {threads}, seed {seed}); load = 1/5/15-min load average "
          "before the update")
    line("variant", names)
    line("update wall s", [r["update"]["wall_s"] for r in rows.values()])
    line("update CPU s", [r["update"]["cpu_s"] for r in rows.values()])
    line("  of it: training loop s", [r["train_s"] for r in rows.values()])
    line("  of it: containment s", [r["contain_s"] for r in rows.values()])
    line("load before update", ["/".join(f"{x:.1f}" for x in r["update"]["load"]) for r in rows.values()])
    line("dynamic after containment", [r["dynamic_after"] for r in rows.values()])
    line("model file bytes", [r["model_bytes"] for r in rows.values()])
    from anigs.stages.export import Outputs as ExportOutputs

    for f in (ExportOutputs.LAYOUT["ply"].name, ExportOutputs.LAYOUT["compact"].name):
        line(f"export {f} bytes", [r["export_bytes"].get(f, "-") for r in rows.values()])
    if all("metrics" in r for r in rows.values()):
        for k, fmt in (("gt/amplitude_w1", ".6f"), ("gt/frequency_w1", ".5f"), ("gt/rms_amplitude_ratio", ".4f"),
                       ("static_outside_mask_still", ".6f"), ("static_abs_diff", ".3e"), ("dynamic_flow", ".5f"),
                       ("multiview/psnr_novel", ".3f")):
            line(k, [format(r["metrics"].get(k, float("nan")), fmt) for r in rows.values()])
    for region in REGION_GT_CYCLES:
        if not all(region in r["effects"] for r in rows.values()):
            continue
        e = [r["effects"][region] for r in rows.values()]
        n = e[0]["n_learned"], e[0]["n_gt"]
        line(f"{region} (K; learned/GT n={n[0]}/{n[1]})", [x["K"] for x in e])
        line(f"  {region} amplitude W1", [f"{x['amplitude_w1']:.6f}" for x in e])
        line(f"  {region} frequency W1", [f"{x['frequency_w1']:.5f}" for x in e])
        line(f"  {region} rms amplitude ratio", [f"{x['rms_amplitude_ratio']:.4f}" for x in e])
        line(f"  {region} hf share (GT)", [f"{x['hf']:.4f} ({x['hf_gt']:.3f})" for x in e])
    for n, r in rows.items():
        if "identical_to_before" in r:
            print(f"{n}: model file byte-identical to the code before the key: {r['identical_to_before']}; "
                  f"to the demo's own round-{R} model: {r['same_bytes_as_demo']}")


if __name__ == "__main__":
    sys.exit(main())
