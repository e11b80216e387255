"""Peak memory of a model update's target clips, before and after issue 28 (every clip loaded as
float32 -> read from disk a frame at a time, :class:`anigs.animate.target_frames.ClipFrames`).

    python benchmarks/update_memory.py make DIR VIEWS FRAMES WIDTH HEIGHT   # the target clips (float16 .npz)
    python benchmarks/update_memory.py run DIR before|after [STEPS]         # load them, STEPS update steps

``make`` writes VIEWS clips of FRAMES frames at WIDTHxHEIGHT as the refine stage stores them
(float16 frames, stored .npz, a ring camera each in the metadata; smooth moving stripes). ``run``
loads them as the update stage did before (``anigs.video.load_clip``: float32 [T,H,W,3] per view)
or does now (``training_views``), then runs STEPS steps (default 5) of ``run_update`` on a small
swaying shrub (tests/_scenes.py) seen by those cameras. One mode per process, so each peak is its
own. Prints JSON: peak RSS (MiB), RSS before loading (Python + torch), the targets' bytes as
float32, the MiB the loaded targets hold, CPU seconds of loading and of the steps.
"""
from __future__ import annotations

import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def make(folder: str, views: int, frames: int, width: int, height: int) -> dict:
    from anigs.io import write_npz
    from tests._scenes import ring_cameras

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    x = np.linspace(0, 6 * np.pi, width, dtype=np.float32)[None, :, None]
    y = np.linspace(0, 4 * np.pi, height, dtype=np.float32)[:, None, None]
    rgb = np.array([0.0, 2.1, 4.2], np.float32)[None, None, :]
    for v, cam in enumerate(ring_cameras(views, width, height)):
        first = (0.5 + 0.4 * np.sin(x + 0.7 * y + rgb + v)).astype(np.float16)
        clip = np.empty((frames, height, width, 3), np.float16)
        for t in range(frames):  # the stripes move 2 px a frame
            clip[t] = np.roll(first, 2 * t, axis=1)
        meta = {"camera": cam.to_dict(), "fps": 24}
        write_npz(out / f"v{v:02d}.npz", compress=False, frames=clip, meta=np.array(json.dumps(meta)))
    return {"views": views, "frames": frames, "width": width, "height": height,
            "float16_bytes_on_disk": views * frames * width * height * 3 * 2}


def run(folder: str, mode: str, steps: int = 5) -> dict:
    import torch

    from anigs.animate.training_views import training_views
    from anigs.animate.update import ViewData, run_update
    from anigs.animate.config import UpdateConfig
    from anigs.cameras import Camera
    from anigs.video import load_clip
    from tests._scenes import sway_scene

    torch.set_num_threads(1)
    paths = sorted(str(p) for p in Path(folder).glob("v*.npz"))
    G, mask = sway_scene(n_dyn=200, grid=15)
    cfg = UpdateConfig(steps=steps, views_per_step=2, num_bases=4, lambda_cano=0.0, effect_num_bases={}, seed=0)
    base = _rss_mib()
    c0 = time.process_time()
    if mode == "before":
        views = []
        for p in paths:
            clip, meta = load_clip(p)
            views.append(ViewData(Camera.from_dict(meta["camera"]), torch.from_numpy(clip)))
        held = sum(v.clip.numel() * v.clip.element_size() for v in views)
    elif mode == "after":
        views = training_views(G, paths, None, None, None, None, cfg)
        held = sum(v.clip.held_bytes for v in views)
    else:
        raise SystemExit(f"mode must be before or after, got {mode!r}")
    c1 = time.process_time()
    loaded = _rss_mib()
    res = run_update(G, mask, views, cfg, progress=False)
    c2 = time.process_time()
    T, H, W, _ = views[0].clip.shape
    return {"mode": mode, "views": len(views), "frames": T, "width": W, "height": H, "steps": steps,
            "targets_float32_mib": round(len(views) * T * H * W * 3 * 4 / 2**20),
            "held_mib": round(held / 2**20), "rss_before_loading_mib": round(base),
            "rss_after_loading_mib": round(loaded), "peak_rss_mib": round(_rss_mib()),
            "load_cpu_s": round(c1 - c0, 2), "steps_cpu_s": round(c2 - c1, 2),
            "final_loss": res.history[-1]["loss"]}


if __name__ == "__main__":
    if len(sys.argv) >= 7 and sys.argv[1] == "make":
        print(json.dumps(make(sys.argv[2], *map(int, sys.argv[3:7]))))
    elif len(sys.argv) in (4, 5) and sys.argv[1] == "run":
        print(json.dumps(run(sys.argv[2], sys.argv[3], *map(int, sys.argv[4:]))))
    else:
        raise SystemExit(__doc__)
