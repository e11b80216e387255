"""Stage ``round``: render and refine every view of one round in one process.

    anigs round --static static/ [--model round{r-1}/] --views views/ --view-ids v00 v01 ... \\
        --masks masks/ [--effects effects/] --round R --out round{r}/ \\
        --render-params '{"num_frames": 25}' --refine-params '{"prior": "procedural"}'

The same work as one ``render_clip`` and one ``refine`` job per view, with one Python start-up:
the canonical scene, the round's model and the video prior are loaded once. Every file is
byte-identical to the per-view jobs' (same functions, same seeds, same metadata). The workflow
runs rounds this way locally (``round_jobs: round``, the default there); a cluster runs one job
per view (``round_jobs: view``), so that the views of a round run on separate GPUs.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.stages import refine, render_clip
from anigs.stages.command import parse_params
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.io import write_json

log = logging.getLogger("anigs.round")


class Outputs(contract.RoundOutputs):
    """A round's folder (``round{r}/``): the rendered clips and the targets of its new views. Its
    files are the render_clip and refine stages' (``OUTPUTS``), so it names none itself."""

    @property
    def renders(self) -> render_clip.Outputs:
        """The render_clip stage's files in this folder (the refine stage's input)."""
        return render_clip.Outputs(self.root)


OUTPUTS = (render_clip.Outputs, refine.Outputs)  # what the stage writes: both stages' files


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    views: ViewsOutputs
    masks: MasksOutputs
    view_ids: list[str] = field(metadata={"help": "the round's view ids, e.g. v00 v01"})
    round: int = field(metadata={"help": "round number (seeds the refinement noise)"})
    out: Path = field(metadata={"help": "the round's folder (render/ and target/)"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the folder of the model that renders "
                                                                        "(omit for round 0: static)"})
    effects: EffectsOutputs | None = field(default=None, metadata={"help": "the effects stage's folder: synthesise "
                                                                           "its chosen effects"})
    render_params: str = field(default="{}", metadata={"help": "render_clip params as JSON"})
    refine_params: str = field(default="{}", metadata={"help": "refine params as JSON"})
    timings_json: Path | None = field(default=None, metadata={"help": "JSON file of seconds per view and phase"})


def run(inputs: Inputs, cfg: None = None) -> Outputs:
    """Render each view of ``inputs.view_ids`` with the round's model (none: static) and refine it with its
    mask; the configs are ``inputs``' render and refine params (the stage has no section of its own).
    Seconds per view and phase go to the log (and ``--timings-json``), not into the artifacts."""

    view_ids = inputs.view_ids
    if not view_ids:
        raise ValueError("round: no views given")
    if len(set(view_ids)) != len(view_ids):
        raise ValueError(f"round: duplicate view ids in {view_ids}")
    missing = [v for v in view_ids if not inputs.masks.exists("mask", view=v)]
    if missing:
        raise FileNotFoundError(f"round: no mask for views {missing} in {inputs.masks.root} (run the masks stage)")
    render_cfg = render_clip.RenderClipConfig.from_dict(parse_params(inputs.render_params))
    refine_cfg = refine.RefineConfig.from_dict(parse_params(inputs.refine_params))
    out = Outputs(inputs.out)
    startup_cpu = time.process_time()  # CPU this process spent before the work: interpreter, imports, arguments
    t0 = time.perf_counter()
    model = inputs.model.path("model") if inputs.model is not None else None
    scene = render_clip.load_animated_scene(inputs.static.path("canonical"), render_cfg, model)
    timings = {"load_s": time.perf_counter() - t0, "views": {}}
    priors: dict = {}
    for v in view_ids:
        t1 = time.perf_counter()
        render_clip.run(render_clip.Inputs(static=inputs.static, out=out.root, model=inputs.model, views=inputs.views,
                                           view_id=v), render_cfg, scene=scene)
        t2 = time.perf_counter()
        refine.run(refine.Inputs(render_clip=out.renders, view=v, out=out.root, masks=inputs.masks,
                                 effects=inputs.effects, round=inputs.round), refine_cfg, priors=priors)
        timings["views"][v] = {"render_s": round(t2 - t1, 3), "refine_s": round(time.perf_counter() - t2, 3)}
    timings["load_s"] = round(timings["load_s"], 3)
    timings["total_s"] = round(time.perf_counter() - t0, 3)
    timings["startup_cpu_s"] = round(startup_cpu, 3)
    timings["process_cpu_s"] = round(time.process_time(), 3)
    log.info("round %d: %d views in %.2fs (scene and model load %.2fs; per view: %s)", inputs.round, len(view_ids),
             timings["total_s"], timings["load_s"], timings["views"])
    log.info("round %d: start-up %.2f s of the process's %.2f s CPU", inputs.round, startup_cpu, timings["process_cpu_s"])
    if inputs.timings_json:
        write_json(inputs.timings_json, timings)
    return out
