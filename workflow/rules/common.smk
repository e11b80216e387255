# Shared helpers: scenes, variants, effective config sections, the round plan.
import json
import os

import anigs
import yaml

from anigs.config import scene_pattern, section, workflow_scenes
from anigs.stages.targets import final_targets, queued_view_count, stage_outputs
from anigs.stages.command import stage_command
from anigs.stages.eval import merge_halves, table_row
from anigs.stages.fvd_gt import wanted as fvd_gt_runs
from anigs.stages.refine import listed_effects
from anigs.stages.round_files import RoundFiles, round_folder
from anigs.stages.tradeoff import plot_files, swept_knobs
from anigs.stages.shared_inputs import ground_truth
from anigs.animate.round_policy import baseline_fields, round_seed, still_reason
from anigs.reports.tradeoff import DERIVED_SEP, points_json, stage_owner, workflow_sweep
from anigs.animate.config import METHODS, AnimateConfig
from anigs.weight_inputs import effects_weights, eval_weights, masks_weights, refine_weights

ANIGS_VERSION = anigs.__version__
R = config["results"]
# the scenes config names, their files and the variants checked against the schema when the workflow
# is parsed (anigs.config.workflow_scenes), so a typo fails before any job runs
with open(os.path.join(workflow.basedir, "workflow", "schemas", "config.schema.yaml")) as _f:
    SCHEMA = yaml.safe_load(_f)
SCENES = workflow_scenes(config, SCHEMA, workflow.basedir, DERIVED_SEP)
ALL_SCENES = dict(SCENES)  # and the accuracy-versus-time sweep's derived scenes (added below)


SYNTH_SCENES = scene_pattern(SCENES, "synthetic")
PHOTO_SCENES = scene_pattern(SCENES, "photos")
COLMAP_SCENES = scene_pattern(SCENES, "colmap")  # a COLMAP project: no capture job, no SfM (colmap_import)
SFM_SCENES = f"{SYNTH_SCENES}|{PHOTO_SCENES}"  # the scenes whose cameras anigs's SfM finds


wildcard_constraints:
    scene="[A-Za-z0-9_.-]+",
    variant="[A-Za-z0-9_-]+",
    round=r"[1-9][0-9]*",
    view=r"v[0-9][0-9]+",


def sec(scene, name, variant="full"):
    """Effective config section for (scene, variant), the run's seed, device and the scene's background handed in."""
    return section(config, ALL_SCENES[scene], variant, name, SCHEMA)


def jparams(name, extra=None):
    """params: the section as canonical JSON (a change re-runs exactly the affected jobs)."""

    def fn(wc):
        d = sec(wc.scene, name, getattr(wc, "variant", "full"))
        if extra is not None:
            d = {**d, **extra(wc)}
        return json.dumps(d, sort_keys=True)

    return fn


def is_synthetic(scene):
    return ALL_SCENES[scene]["source"] == "synthetic"


def splat_of(scene):
    """The scene's splat trained elsewhere (``splat:``), imported by the static stage; None: anigs fits."""
    return ALL_SCENES[scene].get("splat")


def num_views(scene):
    """The views the queue holds, read from the views stage's queue once that checkpoint has run: it
    leaves out views whose dynamic region is negligible (views.min_dynamic_fraction)."""
    return queued_view_count(checkpoints.views.get(scene=stage_owner(scene, "views")).output.views)


def plan(scene, variant):
    return AnimateConfig.from_dict(sec(scene, "animate", variant)).plan(num_views(scene))


def method_of(scene, variant):
    """The variant's animation method (animate.method): anigs, or a baseline."""
    return sec(scene, "animate", variant)["method"]


def stage_dir(scene, stage):
    """Output folder of per-scene ``stage`` (capture, sfm, static, views, masks) that ``scene`` uses:
    its own, or for a derived scene of the sweep its base scene's upstream of the swept stage."""
    return stage_out(stage, scene=stage_owner(scene, stage))


def stage_folder(stage):
    """Input function: the ``stage`` folder the job's scene uses (:func:`stage_dir`)."""
    return lambda wc: stage_dir(wc.scene, stage)


def wants_gpu(scene, variant="full"):
    """1 when a job of this scene asks for a GPU (an explicit cuda device or the LTX prior)."""
    dev = str(config["device"])
    return int(dev.startswith("cuda") or sec(scene, "refine", variant)["prior"] == "ltx")


# GPU-only settings on a machine without a GPU fail here, before any job starts (local runs).
if workflow.local_exec and str(config["device"]).startswith("cuda"):
    from anigs.device import check_workflow_device  # (imports torch: only when a GPU is asked for)

    check_workflow_device(config["device"])


# ---- input/param helpers of the stage rules ----

VARIANT_DIR = f"{R}/{{scene}}/{{variant}}"


def _frames(wc):
    return {"num_frames": sec(wc.scene, "animate", wc.variant)["frames"]}


def _gt_effects(scene):
    """The effects refine synthesises by name (anigs.stages.refine.listed_effects); None: the effects
    stage's choice."""
    return listed_effects(is_synthetic(scene), sec(scene, "effects")["requested"])


def _refine_extra(wc):
    """The scene's prompt and effects: a synthetic scene's listed effects, else the effects stage's
    choice, read at run time (--effects)."""
    s = ALL_SCENES[wc.scene]
    return {"prompt": s.get("prompt", ""), "effects": _gt_effects(wc.scene) or []}


def _effects_prompt(wc):
    """The scene's prompt for the effects stage (with `effects: auto` it names the kinds that may move)."""
    prompt = ALL_SCENES[wc.scene].get("prompt")
    return {} if prompt is None else {"prompt": str(prompt)}


def _effects_json(wc):
    return [] if _gt_effects(wc.scene) is not None else [stage_file_of(wc.scene, "effects", "effects")]


# A round's render and refine work: one job per round (one Python start-up) for local runs, one
# job per view under a cluster executor (also inside its jobs, which parse this file again).
ROUND_JOBS = config["round_jobs"] if config["round_jobs"] != "auto" else ("round" if workflow.local_exec else "view")


def rounds(scene, variant):
    """The round files of (scene, variant) (anigs.stages.round_files)."""
    return RoundFiles(plan(scene, variant), R, scene, variant, ROUND_JOBS == "round")


def round_files(name):
    """Input function: the job's round's files ``name`` (a RoundFiles method: render_model,
    targets, earlier_targets, init_model)."""
    return lambda wc: getattr(rounds(wc.scene, wc.variant), name)(int(wc.round))


def _update_extra(wc):
    return {"seed": round_seed(config["seed"], int(wc.round))}  # the run's seed, one per round


# ---- stage commands: built from each stage's Inputs (anigs/stages/<name>.py: Inputs.argv), so a
# rule names the upstream stages' folders and scalars, and one artifact has one flag everywhere ----


def _folder(files):
    """The folder of an input's first file (a model: its round's folder), None when there is none."""
    return os.path.dirname(files[0]) if files else None


def update_command(wc, input):
    """Round r's model update: trains on one target clip per view of its dataset; the update stage
    decides from --round/--rounds whether it contains the motion (update.contain_rounds)."""
    rf, r = rounds(wc.scene, wc.variant), int(wc.round)
    return stage_command(
        "update",
        jparams("update", _update_extra)(wc),
        static=stage_dir(wc.scene, "static"),
        out=rf.folder(r),
        masks=stage_dir(wc.scene, "masks"),
        targets=rf.target_files(r),
        init=_folder(input.init),
        views=stage_dir(wc.scene, "views"),
        round=r,
        rounds=rf.plan.num_rounds,
        **baseline_fields(sec(wc.scene, "animate", wc.variant), sec(wc.scene, "update", wc.variant)),
    )


def _chosen_effects(scene):
    """The effects the effects stage chose for ``scene`` (read once that checkpoint has run: the DAG
    below it depends on what the scene contains)."""
    checkpoints.effects.get(scene=stage_owner(scene, "effects"))  # (raises until that job has run)
    return stage_outputs("effects")(stage_dir(scene, "effects")).json("effects")


def animates(scene):
    """False when the effects stage chose no effect: no round runs, the model is a still one."""
    return bool(_chosen_effects(scene)["chosen"])


def still_model(scene="{scene}", variant="{variant}"):
    """The still model (the update stage's model file in the variant's ``still`` folder: the still rule)."""
    return str(stage_outputs("update")(f"{R}/{scene}/{variant}/still").path("model"))


def final_model_of(scene, variant):
    """The model the final stages use: the last round's, or the still model when nothing moves."""
    return rounds(scene, variant).final_model() if animates(scene) else still_model(scene, variant)


def final_model(wc):
    return final_model_of(wc.scene, wc.variant)


def _still_reason(wc):
    return still_reason(_chosen_effects(wc.scene))


def _table_row(wc):
    """The variant's table row (anigs.stages.eval.table_row) as the ``--method --variant`` fields."""
    return dict(zip(("method", "variant"), table_row(method_of(wc.scene, wc.variant), wc.variant)))


def eval_command(wc, part, **inputs):
    params = jparams("eval")(wc)
    return stage_command("eval", params, out=job_out("eval", wc), scene=wc.scene, part=part, **_table_row(wc), **inputs)


# ---- accuracy versus time: the sweep's points are variants, or derived scenes for per-scene
# stages (see anigs/reports/tradeoff.py) ----
TRADEOFF = workflow_sweep(config, SCENES, ALL_SCENES, sec)  # scene -> [SweepPoint]


def tradeoff_points():
    """Every scene's sweep points (`snakemake tradeoff`); an empty sweep is an error naming the key."""
    if not swept_knobs(config.get("tradeoff", {})):
        raise ValueError("config: tradeoff.knobs is empty; name the knobs to sweep (see config/README.md)")
    return TRADEOFF


# ---- the stages' files, named by their Outputs (anigs/stages/<name>.py: FOLDER, LAYOUT): the
# rules spell no file name of a stage's folder ----
STUDY = "anigs.study.layout"  # the study folder's Outputs (`anigs study build`: not a pipeline stage)


def stage_out(stage, key=None, kind="Outputs", **fields):
    """File ``key`` (None: the folder) of ``stage``'s Outputs (``kind``: another Outputs type of the
    module, e.g. fvd_gt's ReferenceOutputs) under the results root, fields not given left as
    wildcards: a rule's output pattern, or a path (:meth:`anigs.contract.Outputs.under`)."""
    return stage_outputs(stage, kind).under(R, key, **fields)


def job_out(stage, wc, key=None, kind="Outputs"):
    """:func:`stage_out` with the job's wildcards filled in (its own folder: no derived-scene mapping)."""
    return stage_out(stage, key, kind, **dict(wc.items()))


def layout_name(stage, key, kind="Outputs"):
    """The name of file ``key`` in ``stage``'s folder (``{view}_overlay.png``)."""
    return stage_outputs(stage, kind).LAYOUT[key].name


def stage_file_of(scene, stage, key):
    """File ``key`` of the ``stage`` folder that ``scene`` uses (:func:`stage_dir`)."""
    return stage_out(stage, key, scene=stage_owner(scene, stage))


def stage_file(stage, key):
    """Input function: :func:`stage_file_of` for the job's scene."""
    return lambda wc: stage_file_of(wc.scene, stage, key)


def gt_of(scene, key):
    """A ground-truth file of the capture stage (``gt_cameras``, ``gt_labels``, ...) of ``scene``."""
    return stage_file_of(scene, "capture", key)


def gt_fields(scene):
    """A synthetic scene's ground truth as the views and masks stages' ``GroundTruthInputs`` fields
    (anigs.stages.shared_inputs.ground_truth); none on photo scenes."""
    return ground_truth(R, stage_owner(scene, "capture")) if is_synthetic(scene) else {}


def gt_inputs(wc):
    """Synthetic scenes: the ground truth the views and masks stages read."""
    return list(gt_fields(wc.scene).values())
