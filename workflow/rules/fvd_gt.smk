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
    if not fvd_gt_wanted(wc.scene, wc.variant, "eval"):
        return []
    return [out_path("fvd_gt", f"{R}/{wc.scene}/{wc.variant}/eval", "record")]


def fvd_gt_table_inputs():
    return [f"{R}/{s}/{v}/eval/fvd_gt.json" for s in SCENES for v in config["table_variants"] if fvd_gt_wanted(s, v)]


FVD_GT_REF = f"{R}/{{scene}}/fvd_gt"


def _fvd_gt_scene(wc):
    """The fvd_gt stage's scene inputs (the capture's ground truth, the reconstruction's frame and
    canonical scene) and the eval section (its I3D network)."""
    return {"capture": stage_dir(wc.scene, "capture"), "sfm": stage_dir(wc.scene, "sfm"),
            "static": stage_dir(wc.scene, "static"),
            "eval_params": jparams("eval", lambda wc: {"device": config["device"], "seed": config["seed"]})(wc)}


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
        cmd=lambda wc: stage_command("fvd_gt", jparams("fvd_gt", lambda wc: {"seed": config["seed"]})(wc),
                                     **_fvd_gt_scene(wc), out=f"{R}/{wc.scene}/fvd_gt", reference=True,
                                     frames=sec(wc.scene, "animate")["frames"]),
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
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


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
        cmd=lambda wc, input: stage_command("fvd_gt", jparams("fvd_gt", lambda wc: {"seed": config["seed"]})(wc),
                                            **_fvd_gt_scene(wc), out=f"{R}/{wc.scene}/{wc.variant}/eval",
                                            reference_dir=f"{R}/{wc.scene}/fvd_gt", model=_folder([input.model]),
                                            scene=wc.scene, method=_table_row(wc)[0], variant=_table_row(wc)[1]),
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
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
