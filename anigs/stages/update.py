"""Stage ``update``: train the deformation field of one round on the round's target clips.

    anigs update --static static/ [--init round{r-1}/] --targets round{r}/target/A.npz ... \\
        --views views/ --masks masks/ [--round R --rounds N] --out round{r}/ --params '{...update...}'

Cameras: ``--camera-json`` (one per target), else ``--views`` with ``--view-ids`` (default: the
targets' file stems), else each target's metadata. Static references (L_cano): ``--static-refs``,
else renders of the canonical scene. ``--masks``: the masks stage's folder: its dynamic set, its
effect labels (for ``effect_num_bases`` and ``effect_limits``) and, with ``contain``, the view
masks the motion is contained in (:mod:`anigs.animate.containment`) in the rounds that
``contain_rounds`` names (:func:`contains`). ``--method lifting|physics`` fits that baseline
instead; ``--still REASON`` writes a model in which nothing moves. If the update diverges, the last
good state is written to ``model.last_good.pt``.
"""
from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass, field
from pathlib import Path

from anigs.animate.round_policy import contains
from anigs.animate.config import UpdateConfig
from anigs import contract
from anigs.stages.command import parse_params
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.contract import File
from anigs.animate.containment import contain_result
from anigs.animate.deform import load_model, save_model, resolve_num_bases
from anigs.animate.still import write_still_model
from anigs.animate.training_views import dynamic_set, training_views
from anigs.animate.update import run_update
from anigs.animate.update_job import round_record, sds_term
from anigs.baselines import run_baseline
from anigs.gaussians import Gaussians
from anigs.io import write_json, read_json
from anigs.views import cameras_from_views

Config = UpdateConfig  # the `update` config section

log = logging.getLogger("anigs.update")


class Outputs(contract.RoundOutputs):
    """A round's model folder (``round{r}/``; ``still/`` when nothing moves)."""

    LAYOUT = {"model": File("model.pt", "deformation (DCT coefficients [M,K,3]/[M,K,4], dynamic index [M]) + "
                                        "canonical positions [N,3] (anigs.animate.deform.save_model)"),
              "log": File("update.json", "loss history, timing, containment counts", optional=True),
              "last_good": File("model.last_good.pt", "the last good state when the update diverged", optional=True)}

    def load(self, canonical=None):
        """(canonical Gaussians with the model's positions, or None; deformation; payload) of ``model.pt``."""

        return load_model(self.path("model"), canonical)


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    out: Path = contract.output_folder(Outputs, "the round's folder")
    masks: MasksOutputs | None = None
    targets: list[str] | None = field(default=None, metadata={"help": "target clips (.npz), one per training view"})
    init: Outputs | None = field(default=None, metadata={"help": "the previous round's folder (omit: start from zero)"})
    views: ViewsOutputs | None = None
    view_ids: list[str] | None = field(default=None, metadata={"help": "view ids of the targets (default: stems)"})
    camera_json: list[str] | None = field(default=None, metadata={"help": "one camera JSON per target"})
    static_refs: list[str] | None = field(default=None, metadata={"help": "static reference images, one per target"})
    round: int | None = field(default=None, metadata={"help": "this round (with --rounds: containment policy)"})
    rounds: int | None = field(default=None, metadata={"help": "number of rounds of the plan"})
    prior: str | None = field(default=None, metadata={"help": "video prior of the SDS term (lambda_sds > 0)"})
    prior_params: str | None = field(default=None, metadata={"help": "that prior's config section as JSON"})
    prompt: str | None = field(default=None, metadata={"help": "text prompt of the SDS term"})
    method: str | None = field(default=None, metadata={"help": "lifting | physics: fit that baseline instead"})
    method_params: str | None = field(default=None, metadata={"help": "the baseline's config as JSON"})
    still: str | None = field(default=None, metadata={"help": "nothing to animate: a model in which nothing moves "
                                                              "(the reason is stored)"})
    frames: int | None = field(default=None, metadata={"help": "with --still: frames T (animate.frames)"})


def run(inputs: Inputs, cfg: UpdateConfig) -> Outputs:
    """Train the round's model on ``inputs.targets``; writes ``model.pt`` and ``update.json``."""

    out = Outputs(inputs.out)
    canonical_path, masks = inputs.static.path("canonical"), inputs.masks
    if not inputs.targets or masks is None:
        raise ValueError("update: --targets and --masks are required (or --still REASON when nothing moves)")
    canonical_ply = Gaussians.load_ply(canonical_path)
    has_labels = masks.exists("effect_labels")
    dynamic = dynamic_set(masks.array("dynamic", shape=(None,)), canonical_ply.num, str(masks.path("dynamic")),
                          masks.array("effect_labels", "iu") if has_labels else None, str(masks.path("effect_labels")))
    views_json = inputs.views.path("views") if inputs.views else None
    views = training_views(canonical_ply, inputs.targets, views_json, inputs.view_ids, inputs.camera_json,
                           inputs.static_refs, cfg)
    cams = [v.camera for v in views]
    canonical, init = canonical_ply, None
    if inputs.init is not None:
        canonical, init, _ = inputs.init.load(canonical_ply)
    sds = sds_term(cfg, inputs.prior, parse_params(inputs.prior_params) if cfg.lambda_sds > 0 else {}, inputs.prompt)
    result = run_update(canonical, dynamic, views, cfg, init=init, sds_fn=sds, failure_path=out.path("last_good"))
    contained = None
    if contains(cfg, inputs.round, inputs.rounds) and result.deformation.num_dynamic:

        all_cams = cameras_from_views(read_json(views_json)) if views_json else cams
        contained = contain_result(result, canonical_ply, all_cams, [masks.view_mask(c.name) >= 0.5 for c in all_cams],
                                   cfg)
    init_model = str(inputs.init.path("model")) if inputs.init is not None else None
    save_model(out.path("model"), result.deformation, result.canonical, cfg.to_dict(),
               store_all_attributes=cfg.param_groups == "all",
               extra={"targets": [str(t) for t in inputs.targets], "init_model": init_model, "skipped": result.skipped})
    d = result.deformation
    log.info("wrote %s (%d dynamic Gaussians, K=%d, T=%d)", out.path("model"), d.num_dynamic, d.num_bases, d.num_frames)
    write_json(out.path("log"), round_record(result, cfg, contained))
    return out


def run_other(inputs: Inputs, cfg: UpdateConfig) -> Outputs:
    """``--still``: the model in which nothing moves; ``--method``: a baseline's fit (same model.pt format)."""

    out = Outputs(inputs.out)
    if inputs.still:

        if not inputs.frames:
            raise ValueError("update --still: give --frames T (animate.frames)")
        K = resolve_num_bases(cfg.num_bases, inputs.frames, log)
        write_json(out.path("log"), write_still_model(inputs.static.path("canonical"), out.path("model"),
                                                      inputs.frames, K, inputs.still))
        return out

    if not inputs.targets or inputs.masks is None:
        raise ValueError("update: --targets and --masks are required")
    run_baseline(inputs.method, inputs.static.path("canonical"), inputs.masks.path("dynamic"), inputs.targets,
                 out.path("model"), parse_params(inputs.method_params),
                 view_json=inputs.views.path("views") if inputs.views else None, view_ids=inputs.view_ids,
                 log_json=out.path("log"))
    return out


# ---- command line: anigs update ----

def main(args: argparse.Namespace) -> int:
    inputs = Inputs.from_args(args)
    cfg = UpdateConfig.from_dict(parse_params(args.params))
    if inputs.method not in (None, "anigs", "lifting", "physics"):
        raise ValueError(f"update: --method {inputs.method!r}; choose anigs, lifting or physics")
    (run_other if inputs.still or inputs.method not in (None, "anigs") else run)(inputs, cfg)
    return 0
