# anigs workflow: static 3DGS -> animated 3DGS (AniGS). See README.md and config/README.md.
import os

from snakemake.utils import min_version, validate

from anigs.config import check_workflow_config
from anigs.registry import STAGES

min_version("8.0")


# the defaults; --configfile FILE overrides them key by key (works from any working directory)
configfile: os.path.join(workflow.basedir, "config", "config.yaml")


# a key moved or renamed since (static.seed: now the top-level seed) fails naming where it is set now
check_workflow_config(config, os.path.join(workflow.basedir, "workflow", "schemas", "config.schema.yaml"))
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
include: "workflow/rules/targets.smk"


# Named targets: `all` (the default) and `all_<stage>` for every stage of the registry
# (anigs/registry.py STAGES): what that stage's jobs write for every scene and variant
# (workflow/rules/targets.smk); `all_animate`, every variant's final model, is also `animate`.
localrules:
    all,
    animate,
    eval,
    tables,
    study,


rule all:
    default_target: True
    input:
        final_targets(R, list(SCENES), config["variants"]),


rule animate:
    input:
        targets_of("animate"),


for _stage in STAGES:

    rule:
        name:
            f"all_{_stage.name}"
        input:
            targets_of(_stage.name),
        localrule: True
