# anigs workflow: static 3DGS -> animated 3DGS (AniGS). See README.md and config/README.md.
import os

from snakemake.utils import min_version, validate

min_version("8.0")


# the defaults; --configfile FILE overrides them key by key (works from any working directory)
configfile: os.path.join(workflow.basedir, "config", "config.yaml")


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/inputs.smk"
include: "workflow/rules/capture.smk"
include: "workflow/rules/reconstruct.smk"
include: "workflow/rules/views.smk"
include: "workflow/rules/animate.smk"
include: "workflow/rules/final.smk"
include: "workflow/rules/fvd_gt.smk"
include: "workflow/rules/eval.smk"


# Named targets. A stage's rule carries the stage's name (the stages: STAGES in
# anigs/registry.py; those that combine scenes are targets themselves); the targets that
# build one stage for every scene and variant are all_<stage>.
localrules:
    all,
    all_static,
    animate,
    all_final,
    all_export,
    all_eval,
    eval,
    tables,
    study,


rule all:
    default_target: True
    input:
        final_targets(),


rule all_static:
    input:
        [stage_out("static", "canonical", scene=s) for s in SCENES],


rule animate:
    input:
        lambda wc: [final_model_of(s, v) for s in SCENES for v in config["variants"]],


rule all_final:
    input:
        [stage_out("final", "summary", scene=s, variant=v) for s in SCENES for v in config["variants"]],


rule all_export:
    input:
        [stage_out("export", "sidecar", scene=s, variant=v) for s in SCENES for v in config["variants"]],


rule all_eval:
    input:
        [stage_out("eval", "metrics", scene=s, variant=v) for s in SCENES for v in config["variants"]],
