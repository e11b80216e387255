# FVD against the ground-truth motion (synthetic scenes): evaluation-only views, the ground truth's
# I3D features once per scene, then each variant's clips at the same views (anigs/stages/fvd_gt.py).
# `fvd_gt.when`: tables (default: `snakemake tables` computes it, the default target does not),
# always (also the default target, merged into metrics.json), never.


def fvd_gt_wanted(scene, variant="full", target="tables"):
    """Whether FVD-GT runs for (scene, variant) when ``target`` (tables | eval) is built."""
    when = sec(scene, "fvd_gt", variant)["when"]
    return is_synthetic(scene) and (when == "always" or (when == "tables" and target == "tables"))


def _fvd_gt_eval_input(wc):
    """eval: the FVD-GT record joins metrics.json with fvd_gt.when: always."""
    return [f"{R}/{wc.scene}/{wc.variant}/eval/fvd_gt.json"] if fvd_gt_wanted(wc.scene, wc.variant, "eval") else []


def fvd_gt_table_inputs():
    return [f"{R}/{s}/{v}/eval/fvd_gt.json" for s in SCENES for v in config["table_variants"] if fvd_gt_wanted(s, v)]


FVD_GT_REF = f"{R}/{{scene}}/fvd_gt"


rule fvd_gt_reference:
    input:
        gt=lambda wc: [gt_file(wc.scene, n) for n in ("gaussians.ply", "labels.npy", "anchors.npy", "motion.json",
                                                        "cameras.json")],
        cameras=stage_path("sfm", "cameras.json"),
        ply=stage_path("static", "canonical.ply"),
    output:
        ref=f"{FVD_GT_REF}/reference.json",
        views=f"{FVD_GT_REF}/views.json",
    params:
        p=jparams("fvd_gt", lambda wc: {"seed": config["seed"]}),
        ep=jparams("eval", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        frames=lambda wc: sec(wc.scene, "animate")["frames"],
        gt=lambda wc: f"{stage_dir(wc.scene, 'capture')}/gt",
        out=lambda wc: f"{R}/{wc.scene}/fvd_gt",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/fvd_gt_reference.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/fvd_gt_reference.tsv"
    threads: 2
    resources:
        mem_mb=6000,
        runtime=120,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} fvd_gt --reference --gt-dir {params.gt:q} --cameras {input.cameras:q} "
        "--canonical {input.ply:q} --frames {params.frames} --out {params.out:q} --params {params.p:q} "
        "--eval-params {params.ep:q} > {log} 2>&1"


rule fvd_gt:
    input:
        ref=f"{FVD_GT_REF}/reference.json",
        views=f"{FVD_GT_REF}/views.json",
        ply=stage_path("static", "canonical.ply"),
        model=final_model,
        cameras=stage_path("sfm", "cameras.json"),
        gt=lambda wc: [gt_file(wc.scene, "cameras.json")],
    output:
        f"{R}/{{scene}}/{{variant}}/eval/fvd_gt.json",
    params:
        p=jparams("fvd_gt", lambda wc: {"seed": config["seed"]}),
        ep=jparams("eval", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        gt=lambda wc: f"{stage_dir(wc.scene, 'capture')}/gt",
        refdir=lambda wc: f"{R}/{wc.scene}/fvd_gt",
        method=_eval_method,
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/{{variant}}/logs/fvd_gt.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/fvd_gt.tsv"
    threads: 2
    resources:
        mem_mb=6000,
        runtime=120,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} fvd_gt --reference-dir {params.refdir:q} --model {input.model:q} "
        "--canonical {input.ply:q} --cameras {input.cameras:q} --gt-dir {params.gt:q} --scene {wildcards.scene} "
        "{params.method} --out {output:q} --params {params.p:q} --eval-params {params.ep:q} > {log} 2>&1"
