"""CPU cost of the VBench metrics beside the other weight-free metrics on one variant's final clips.

    python benchmarks/vbench_cost.py results/demo/physdreamer [--repeat 2]

Process CPU seconds, one thread: what the VBench figures add to the final job's clip metrics.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    import torch

    from anigs.metrics.config import EvalConfig

    from anigs.metrics.suite import clip_fps, find_clips, load_any_clip, weightfree_metrics
    from anigs.metrics.vbench import vbench_metrics

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("variant_dir", type=Path, help="results/{scene}/{variant} (its final/clips, the scene's masks)")
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    torch.set_num_threads(1)
    from anigs.stages.final import Outputs as FinalOutputs
    from anigs.stages.masks import Outputs as MasksOutputs

    files = find_clips([FinalOutputs(a.variant_dir / "final").path("clips")])
    clips = {v: load_any_clip(p) for v, p in files.items()}
    cfg = EvalConfig.from_dict({})
    for _ in range(a.repeat):
        t0 = time.process_time()
        weightfree_metrics(clips, MasksOutputs(a.variant_dir.parent / "masks"), cfg)
        t1 = time.process_time()
        vbench_metrics(clips, {v: clip_fps(p) for v, p in files.items()}, cfg.flow_preset)
        t2 = time.process_time()
        print(f"{len(clips)} clips: weight-free {t1 - t0:.1f} CPU s, VBench {t2 - t1:.1f} CPU s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
