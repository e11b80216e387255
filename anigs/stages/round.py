"""Stage ``round``: render and refine every view of one round in one process.

    anigs round --canonical static/canonical.ply [--model round{r-1}/model.pt] \\
        --view-json views/views.json --views v00,v01,... --masks-dir masks/ --round R \\
        --render-dir round{r}/render --target-dir round{r}/target \\
        --render-params '{"num_frames": 25}' --refine-params '{"prior": "procedural"}' [--effects-json FILE]

The same work as one ``render_clip`` and one ``refine`` job per view, with one Python start-up:
the canonical scene, the round's model and the video prior are loaded once. Every file is
byte-identical to the per-view jobs' (same functions, same seeds, same metadata). The workflow
runs rounds this way locally (``round_jobs: round``, the default there); a cluster runs one job
per view (``round_jobs: view``), so that the views of a round run on separate GPUs.
"""
from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

log = logging.getLogger("anigs.round")


def run(canonical_path: str | Path, views_json: str | Path, view_ids: list[str], masks_dir: str | Path,
        render_dir: str | Path, target_dir: str | Path, render_cfg, refine_cfg, round_: int,
        model_path: str | Path | None = None) -> dict:
    """Render each view of ``view_ids`` to ``render_dir/{view}.npz`` with the model at ``model_path``
    (none: static) and refine it to ``target_dir/{view}.npz`` with ``masks_dir/{view}.png``.
    ``render_cfg``/``refine_cfg``: the ``render_clip`` and ``refine`` configs. Returns seconds per view
    and phase (the log gets them too; the artifacts do not)."""
    from anigs.cameras import load_view_camera
    from anigs.stages import refine, render_clip

    if not view_ids:
        raise ValueError("round: no views given")
    if len(set(view_ids)) != len(view_ids):
        raise ValueError(f"round: duplicate view ids in {view_ids}")
    masks_dir = Path(masks_dir)
    missing = [v for v in view_ids if not (masks_dir / f"{v}.png").is_file()]
    if missing:
        raise FileNotFoundError(f"round: no mask for views {missing} in {masks_dir} (run the masks stage)")
    render_dir, target_dir = Path(render_dir), Path(target_dir)
    render_dir.mkdir(parents=True, exist_ok=True)
    target_dir.mkdir(parents=True, exist_ok=True)
    startup_cpu = time.process_time()  # CPU this process spent before the work: interpreter, imports, arguments
    t0 = time.perf_counter()
    scene = render_clip.load_scene(canonical_path, render_cfg, model_path)
    timings = {"load_s": time.perf_counter() - t0, "views": {}}
    priors: dict = {}
    for v in view_ids:
        t1 = time.perf_counter()
        camera = load_view_camera(views_json, v)
        clip = render_dir / f"{v}.npz"
        render_clip.render_view(scene, camera, clip, render_cfg, canonical_path, model_path, view_id=v)
        t2 = time.perf_counter()
        refine.run(clip, refine.load_mask(masks_dir / f"{v}.png"), target_dir / f"{v}.npz", refine_cfg,
                   round_=round_, view=v, priors=priors)
        t3 = time.perf_counter()
        timings["views"][v] = {"render_s": round(t2 - t1, 3), "refine_s": round(t3 - t2, 3)}
    timings["load_s"] = round(timings["load_s"], 3)
    timings["total_s"] = round(time.perf_counter() - t0, 3)
    timings["startup_cpu_s"] = round(startup_cpu, 3)
    timings["process_cpu_s"] = round(time.process_time(), 3)
    log.info("round %d: %d views in %.2fs (scene and model load %.2fs; per view: %s)", round_, len(view_ids),
             timings["total_s"], timings["load_s"], timings["views"])
    log.info("round %d: start-up %.2f s of the process's %.2f s CPU", round_, startup_cpu, timings["process_cpu_s"])
    return timings


# ---- command line: anigs round ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_canonical

    add_canonical(p)
    p.add_argument("--model", default=None, help="model.pt of the previous round (omit for round 0: static)")
    p.add_argument("--view-json", required=True, help="views JSON of the views stage")
    p.add_argument("--views", required=True, help="comma-separated view ids of the round, e.g. v00,v01")
    p.add_argument("--masks-dir", required=True, help="masks folder with {view}.png")
    p.add_argument("--round", type=int, required=True, help="round number (seeds the refinement noise)")
    p.add_argument("--render-dir", required=True, help="output folder of the rendered clips {view}.npz")
    p.add_argument("--target-dir", required=True, help="output folder of the refined targets {view}.npz")
    p.add_argument("--render-params", default="{}", help="render_clip params as JSON")
    p.add_argument("--refine-params", default="{}", help="refine params as JSON")
    p.add_argument("--effects-json", default=None,
                   help="effects.json of the effects stage: synthesise its chosen effects (replaces params effects)")
    p.add_argument("--timings-json", default=None, help="optional JSON file with seconds per view and phase")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.io import write_json
    from anigs.stages.refine import RefineConfig
    from anigs.stages.render_clip import RenderClipConfig

    render_cfg = RenderClipConfig.from_dict(parse_params(args.render_params))
    refine_cfg = RefineConfig.from_dict(parse_params(args.refine_params)).with_effects_json(args.effects_json)
    views = [v for v in args.views.split(",") if v]
    timings = run(args.canonical, args.view_json, views, args.masks_dir, args.render_dir, args.target_dir,
                  render_cfg, refine_cfg, args.round, model_path=args.model)
    if args.timings_json:
        write_json(args.timings_json, timings)
    return 0
