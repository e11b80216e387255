# FVD against the ground-truth motion (synthetic scenes): evaluation-only views, the ground truth's
# I3D features once per scene, then each variant's clips at the same views (anigs/stages/fvd_gt.py).
# `fvd_gt.when`: tables (default: `snakemake tables` computes it, the default target does not),
# always (also the default target, merged into metrics.json), never.


rule fvd_gt_reference:
    input:
        gt=lambda wc: [
            gt_of(wc.scene, k) for k in ("gt_gaussians", "gt_labels", "gt_anchors", "gt_motion", "gt_cameras")
        ],
        cameras=stage_file("sfm", "cameras"),
        ply=stage_file("static", "canonical"),
    output:
        ref=stage_out("fvd_gt", "reference", "ReferenceOutputs"),
        views=stage_out("fvd_gt", "views", "ReferenceOutputs"),
    log:
        f"{R}/{{scene}}/logs/fvd_gt_reference.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/fvd_gt_reference.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=6000,
        runtime=120,
    params:
        cmd=lambda wc: stage_command(
            "fvd_gt",
            jparams("fvd_gt")(wc),
            **_fvd_gt_scene(wc),
            out=job_out("fvd_gt", wc, kind="ReferenceOutputs"),
            reference=True,
            frames=sec(wc.scene, "animate")["frames"],
        ),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule fvd_gt:
    input:
        ref=stage_out("fvd_gt", "reference", "ReferenceOutputs"),
        views=stage_out("fvd_gt", "views", "ReferenceOutputs"),
        ply=stage_file("static", "canonical"),
        model=final_model,
        cameras=stage_file("sfm", "cameras"),
        gt=lambda wc: [gt_of(wc.scene, "gt_cameras")],
        weights=lambda wc: eval_weights(sec(wc.scene, "eval", wc.variant)),
    output:
        stage_out("fvd_gt", "record"),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/fvd_gt.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/fvd_gt.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=6000,
        runtime=120,
    params:
        cmd=lambda wc, input: stage_command(
            "fvd_gt",
            jparams("fvd_gt")(wc),
            **_fvd_gt_scene(wc),
            out=job_out("fvd_gt", wc),
            reference_dir=stage_out("fvd_gt", kind="ReferenceOutputs", scene=wc.scene),
            model=_folder([input.model]),
            scene=wc.scene,
            **_table_row(wc),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("fvd_gt"),
        ep=jparams("eval"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
