# anigs workflow: static 3DGS -> animated 3DGS (AniGS). See README.md and config/README.md.
import os

from snakemake.utils import min_version, validate

min_version("8.0")


# the defaults; --configfile FILE overrides them key by key (works from any working directory)
configfile: os.path.join(workflow.basedir, "config", "config.yaml")


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/capture.smk"
include: "workflow/rules/reconstruct.smk"
include: "workflow/rules/views.smk"
include: "workflow/rules/animate.smk"
include: "workflow/rules/final.smk"
include: "workflow/rules/eval.smk"


localrules:
    all,
    static,
    animate,
    render,
    export,
    eval,
    tables,
    tradeoff,


rule all:
    input:
        final_targets(),
    default_target: True


rule static:
    input:
        [f"{R}/{s}/static/canonical.ply" for s in SCENES],


rule animate:
    input:
        [model_path(s, v, plan(s, v).num_rounds) for s in SCENES for v in config["variants"]],


rule render:
    input:
        [f"{R}/{s}/{v}/final/final.json" for s in SCENES for v in config["variants"]],


rule export:
    input:
        [f"{R}/{s}/{v}/export/animated.json" for s in SCENES for v in config["variants"]],


rule eval:
    input:
        [f"{R}/{s}/{v}/eval/metrics.json" for s in SCENES for v in config["variants"]],


rule tables:
    input:
        f"{R}/tables/tables.json",


rule tradeoff:
    input:
        lambda wc: tradeoff_targets(),
