# Shared helpers: scenes, variants, effective config sections, the round plan.
import json
import os
import re
import shlex

import anigs
import yaml

from anigs.config import check_sections, deep_merge, load_scene, section
from anigs.tradeoff import DERIVED_SEP, get_dotted, knob_filename, stage_owner, sweep_points as _sweep_points
from anigs.animate.plan import METHODS, AnimateConfig, RoundPlan
from anigs.views.queue import queued_view_count

ANIGS_VERSION = anigs.__version__
R = config["results"]
# scene files: relative to the working directory, else to the workflow (when run from elsewhere)
_scene_dir = config["scene_dir"]
if not os.path.isabs(_scene_dir) and not os.path.isdir(_scene_dir):
    _scene_dir = os.path.join(workflow.basedir, _scene_dir)
# scene files and variant overrides are validated against the config schema's sections here, so a
# typo fails when the workflow is parsed, naming the key and the file, before any job runs
with open(os.path.join(workflow.basedir, "workflow", "schemas", "config.schema.yaml")) as _f:
    CONFIG_SCHEMA = yaml.safe_load(_f)
SCENES = {name: load_scene(_scene_dir, name, CONFIG_SCHEMA) for name in config["scenes"]}  # the scenes config names
for _v, _o in config["variant_overrides"].items():
    check_sections(_o, CONFIG_SCHEMA, f"config: variant_overrides.{_v}")
ALL_SCENES = dict(SCENES)  # and the accuracy-versus-time sweep's derived scenes (added below)
for _s in SCENES:
    if DERIVED_SEP in _s:
        raise ValueError(f"config: scene name {_s!r} may not contain {DERIVED_SEP!r} (it marks the sweep's derived scenes)")
for _v in list(config["variants"]) + list(config["table_variants"]):
    if _v not in config["variant_overrides"]:
        raise ValueError(f"config: variant {_v!r} is not defined under variant_overrides "
                         f"(defined: {sorted(config['variant_overrides'])})")


def _names(source):
    names = [re.escape(n) for n, s in SCENES.items() if s["source"] == source]
    return "|".join(names) if names else "(?!x)x"  # never matches when no scene of that kind


SYNTH_SCENES = _names("synthetic")
PHOTO_SCENES = _names("photos")


wildcard_constraints:
    scene="[A-Za-z0-9_.-]+",
    variant="[A-Za-z0-9_-]+",
    round=r"[1-9][0-9]*",
    view=r"v[0-9][0-9]+",


def sec(scene, name, variant="full"):
    """Effective config section for (scene, variant)."""
    return section(config, ALL_SCENES[scene], variant, name)


def with_globals(section_dict, globals_):
    """The section with the workflow's global settings (device, seed, ...) filled in. A section's own
    explicit device (anything but auto) wins over the global one, so `static: {device: cpu}` in a scene
    file is kept rather than silently replaced."""
    out = {**section_dict, **globals_}
    own = section_dict.get("device")
    if "device" in globals_ and own not in (None, "auto"):
        out["device"] = own
    return out


def jparams(name, extra=None):
    """params: the section as canonical JSON (a change re-runs exactly the affected jobs)."""

    def fn(wc):
        d = sec(wc.scene, name, getattr(wc, "variant", "full"))
        if extra is not None:
            d = with_globals(d, extra(wc))
        return json.dumps(d, sort_keys=True)

    return fn


def is_synthetic(scene):
    return ALL_SCENES[scene]["source"] == "synthetic"


def num_views(scene):
    """The views the queue holds, read from views.json once that checkpoint has run: the views stage
    leaves out views whose dynamic region is negligible (views.min_dynamic_fraction)."""
    return queued_view_count(checkpoints.views.get(scene=stage_owner(scene, "views")).output.views)


def view_ids(scene):
    return RoundPlan(num_views(scene)).view_ids()


def plan(scene, variant):
    return AnimateConfig.from_dict(sec(scene, "animate", variant)).plan(num_views(scene))


def method_of(scene, variant):
    """The variant's animation method (animate.method): anigs, or a baseline."""
    return sec(scene, "animate", variant)["method"]


def model_path(scene, variant, r):
    return f"{R}/{scene}/{variant}/round{r}/model.pt"


def stage_dir(scene, stage):
    """Output folder of per-scene ``stage`` (capture, sfm, static, views, masks) that ``scene`` uses:
    its own, or for a derived scene of the sweep its base scene's upstream of the swept stage."""
    return f"{R}/{stage_owner(scene, stage)}/{stage}"


def stage_path(stage, rel=""):
    """Input function: ``stage_dir(wildcards.scene, stage)/rel``."""
    return lambda wc: f"{stage_dir(wc.scene, stage)}/{rel}".rstrip("/")


def gt_file(scene, name):
    return f"{stage_dir(scene, 'capture')}/gt/{name}"


def wants_gpu(scene, variant="full"):
    """1 when a job of this scene asks for a GPU (an explicit cuda device or the LTX prior)."""
    dev = str(config["device"])
    return int(dev.startswith("cuda") or sec(scene, "refine", variant)["prior"] == "ltx")


def final_targets():
    out = []
    for s in SCENES:
        for v in config["variants"]:
            out += [f"{R}/{s}/{v}/final/final.json", f"{R}/{s}/{v}/export/animated.json",
                    f"{R}/{s}/{v}/eval/metrics.json", f"{R}/{s}/{v}/viewer"]
        out.append(stage_out("effects", "effects", s))
    return out


# GPU-only settings on a machine without a GPU fail here, before any job starts (local runs).
if workflow.local_exec and str(config["device"]).startswith("cuda"):
    import torch

    if not torch.cuda.is_available():
        raise ValueError(f"config: device is {config['device']!r} but this machine has no CUDA device; "
                         "use device: auto (or cpu), or submit to a GPU cluster with --profile workflow/profiles/slurm")


# ---- input/param helpers of the stage rules ----

VARIANT_DIR = f"{R}/{{scene}}/{{variant}}"


def _render_model(wc):
    r = plan(wc.scene, wc.variant).render_model_round(int(wc.round))
    return [model_path(wc.scene, wc.variant, r)] if r > 0 else []


def _frames(wc):
    return {"num_frames": sec(wc.scene, "animate", wc.variant)["frames"], "device": config["device"]}


def _gt_effects(scene):
    """A synthetic scene's explicitly listed effects are its ground truth (the refine step
    synthesises them whatever the effects stage found); None: the effects stage chooses."""
    requested = sec(scene, "effects")["requested"]
    return list(requested) if is_synthetic(scene) and requested != "auto" else None


def _refine_extra(wc):
    """The scene's prompt and effects: a synthetic scene's listed effects, else the effects stage's
    choice, read at run time (--effects-json)."""
    s = ALL_SCENES[wc.scene]
    return {"prompt": s.get("prompt", ""), "effects": _gt_effects(wc.scene) or [], "seed": config["seed"]}


def _effects_prompt(wc):
    """The scene's prompt for the effects stage (with `effects: auto` it names the kinds that may move)."""
    prompt = ALL_SCENES[wc.scene].get("prompt")
    return {} if prompt is None else {"prompt": str(prompt)}


def _effects_json(wc):
    return [] if _gt_effects(wc.scene) is not None else [stage_file_of(wc.scene, "effects", "effects")]


# A round's render and refine work: one job per round (one Python start-up) for local runs, one
# job per view under a cluster executor (also inside its jobs, which parse this file again).
ROUND_JOBS = config["round_jobs"] if config["round_jobs"] != "auto" else ("round" if workflow.local_exec else "view")


def round_views(scene, variant, r):
    """Views whose clip round r renders and refines (the views whose target trains round r
    that no earlier round made)."""
    p = plan(scene, variant)
    return [v for v in p.dataset(r) if p.target_round(r, v) == r]


def _targets(wc):
    """Target clips of round r's update: files of per-view refine jobs, or round jobs' folders."""
    p = plan(wc.scene, wc.variant)
    r = int(wc.round)
    base = f"{R}/{wc.scene}/{wc.variant}"
    if ROUND_JOBS == "round":
        return sorted({f"{base}/round{p.target_round(r, v)}/target" for v in p.dataset(r)})
    return [f"{base}/round{p.target_round(r, v)}/target/{v}.npz" for v in p.dataset(r)]


def _earlier_targets(wc):
    """Round jobs (round_jobs: round): the target folders of earlier rounds that round r's update
    trains on (its own folder is the job's output); none in view mode (the update job's inputs)."""
    if ROUND_JOBS != "round":
        return []
    own = f"{R}/{wc.scene}/{wc.variant}/round{wc.round}/target"
    return [t for t in _targets(wc) if t != own]


def _target_files(wc):
    """The update's --targets: one clip per view of round r's dataset."""
    p = plan(wc.scene, wc.variant)
    r = int(wc.round)
    return " ".join(shlex.quote(f"{R}/{wc.scene}/{wc.variant}/round{p.target_round(r, v)}/target/{v}.npz")
                    for v in p.dataset(r))


def _init_model(wc):
    r = int(wc.round)
    return [model_path(wc.scene, wc.variant, r - 1)] if r > 1 else []


def _update_extra(wc):
    return {"device": config["device"], "seed": config["seed"] + 1000 * int(wc.round)}


def _contain_args(wc, input):
    """``--masks`` for the update jobs that contain the motion (``update.contain``,
    ``update.contain_rounds``: the final round, or every round)."""
    u = sec(wc.scene, "update", wc.variant)
    if not u["contain"]:
        return ""
    if u["contain_rounds"] == "every" or int(wc.round) == plan(wc.scene, wc.variant).num_rounds:
        return f"--masks {shlex.quote(str(input.masks))}"
    return ""


def _method_args(wc):
    """A baseline variant's update job fits the baseline (its config: animate.<method>) instead of ours."""
    a = sec(wc.scene, "animate", wc.variant)
    if a["method"] == "anigs":
        return ""
    params = {"num_bases": sec(wc.scene, "update", wc.variant)["num_bases"], **a[a["method"]]}
    return f"--method {a['method']} --method-params {shlex.quote(json.dumps(params, sort_keys=True))}"


def _chosen_effects(scene):
    """The effects the effects stage chose for ``scene`` (read once that checkpoint has run: the DAG
    below it depends on what the scene contains)."""
    path = checkpoints.effects.get(scene=stage_owner(scene, "effects")).output.effects
    with open(path) as f:
        return json.load(f)


def animates(scene):
    """False when the effects stage chose no effect: no round runs, the model is a still one."""
    return bool(_chosen_effects(scene)["chosen"])


def final_model_of(scene, variant):
    """The model the final stages use: the last round's, or the still model when nothing moves."""
    if not animates(scene):
        return f"{R}/{scene}/{variant}/still/model.pt"
    return model_path(scene, variant, plan(scene, variant).num_rounds)


def final_model(wc):
    return final_model_of(wc.scene, wc.variant)


def _still_reason(wc):
    e = _chosen_effects(wc.scene)
    req = e.get("requested")
    return (f"the effects stage chose no effect (requested: {req if isinstance(req, str) else ', '.join(req) or 'none'}; "
            f"detected: {', '.join(e.get('detected') or []) or 'none'}), so nothing moves and no round ran")


def _eval_method(wc):
    """The table row: ours under its variant (Table 5), a baseline under its method name (Tables 1-3)."""
    m = method_of(wc.scene, wc.variant)
    if m == "anigs":
        return f"--method Ours --variant {wc.variant}"
    return f"--method {METHODS[m]} --variant full"


def _eval_gt(wc):
    return f"--gt-dir {stage_dir(wc.scene, 'capture')}/gt" if is_synthetic(wc.scene) else ""


# ---- accuracy versus time: the sweep's points are variants, or derived scenes for per-scene
# stages (see anigs/tradeoff.py) ----
_TO = config.get("tradeoff", {})
TRADEOFF = {}  # scene -> [SweepPoint]
for _s in SCENES:
    TRADEOFF[_s] = _sweep_points(
        _TO.get("knobs", {}), _TO.get("base", "full"), config["variant_overrides"],
        lambda knob, s=_s: get_dotted(sec(s, knob.split(".")[0], _TO.get("base", "full")), knob.split(".")[1:]))
    for _p in TRADEOFF[_s]:
        config["variant_overrides"].setdefault(_p.variant, _p.overrides)
        if _p.scene_tag:
            ALL_SCENES[_p.scene(_s)] = deep_merge(SCENES[_s], _p.scene_overrides)


def tradeoff_points():
    """Every scene's sweep points (`snakemake tradeoff`); an empty sweep is an error naming the key."""
    if not any(v for v in config.get("tradeoff", {}).get("knobs", {}).values()):
        raise ValueError("config: tradeoff.knobs is empty; name the knobs to sweep (see config/README.md)")
    return TRADEOFF


# ---- the scene stages' files, named by their Outputs (anigs/stages/<name>.py: LAYOUT) ----
import importlib as _importlib


def stage_outputs(stage):
    """The ``Outputs`` type of ``stage`` (its folder's layout and loaders)."""
    return _importlib.import_module(f"anigs.stages.{stage}").Outputs


def stage_out(stage, key, scene="{scene}"):
    """Rule output: file ``key`` of ``stage``'s folder of ``scene`` (a wildcard by default)."""
    return stage_outputs(stage).pattern(key, f"{R}/{scene}/{stage}").rstrip("/")


def stage_file_of(scene, stage, key):
    """File ``key`` of the ``stage`` folder that ``scene`` uses (:func:`stage_dir`)."""
    return stage_outputs(stage).pattern(key, stage_dir(scene, stage)).rstrip("/")


def stage_file(stage, key):
    """Input function: :func:`stage_file_of` for the job's scene."""
    return lambda wc: stage_file_of(wc.scene, stage, key)


GT_KEYS = ("gt_labels", "gt_motion", "gt_gaussians", "gt_cameras")  # what masks and views compare with


def gt_of(scene, key):
    """A ground-truth file of the capture stage (``gt_cameras``, ``gt_labels``, ...) of ``scene``."""
    return stage_file_of(scene, "capture", key)


def gt_inputs(wc):
    """Synthetic scenes: the ground truth the views and masks stages read."""
    return [gt_of(wc.scene, k) for k in GT_KEYS] if is_synthetic(wc.scene) else []


def gt_args(wc):
    """``--labels --motion --gt-gaussians --gt-cameras`` of a synthetic scene (views and masks)."""
    if not is_synthetic(wc.scene):
        return ""
    flags = ("--labels", "--motion", "--gt-gaussians", "--gt-cameras")
    return " ".join(f"{f} {shlex.quote(gt_of(wc.scene, k))}" for f, k in zip(flags, GT_KEYS))
