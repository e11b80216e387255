# Stage 9: final renders (videos, slices) and exports of the last round's model.


rule final:
    input:
        ply=stage_file("static", "canonical"),
        model=final_model,
        views=stage_file("views", "views"),
        cameras=stage_file("sfm", "cameras"),
        masks=stage_folder("masks"),
        weights=lambda wc: eval_weights(sec(wc.scene, "eval", wc.variant)),  # FVD's I3D (the clips half)
    output:
        summary=stage_out("final", "summary"),
        slices=report(
            directory(stage_out("final", "slices")),
            patterns=["{name}.png"],
            caption="../report/slices.rst",
            category="Space-time slices",
            subcategory="{scene} {variant}",
        ),
        path=report(
            stage_out("final", "path"),
            caption="../report/final.rst",
            category="Videos",
            subcategory="{scene} {variant}",
        ),
        clip_metrics=stage_out("eval", "clip_metrics"),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/final.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/final.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1  # mostly single-threaded Python and video encoding: the model's metrics run beside it
    resources:
        mem_mb=8000,
        runtime=60,
    params:
        # the final clips' metrics (the eval stage's clips half) in the same process: one start-up less
        cmd=lambda wc, input: stage_command(
            "final",
            jparams("final")(wc),
            static=stage_dir(wc.scene, "static"),
            views=stage_dir(wc.scene, "views"),
            out=job_out("final", wc),
            model=_folder([input.model]),
            sfm=stage_dir(wc.scene, "sfm"),
            masks=stage_dir(wc.scene, "masks"),
        )
        + " --then "
        + eval_command(
            wc,
            "clips",
            final=job_out("final", wc),
            masks=stage_dir(wc.scene, "masks"),
            model=_folder([input.model]),
            static=stage_dir(wc.scene, "static"),
            sfm=stage_dir(wc.scene, "sfm"),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("final"),
        ep=jparams("eval"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule export:
    input:
        ply=stage_file("static", "canonical"),
        model=final_model,
    output:
        sidecar=stage_out("export", "sidecar"),
        ply=stage_out("export", "ply"),
        compact=stage_out("export", "compact"),
        glb=stage_out("export", "glb"),
        spz=stage_out("export", "spz"),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/export.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/export.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        cmd=lambda wc, input: stage_command(
            "export",
            jparams("export")(wc),
            static=stage_dir(wc.scene, "static"),
            model=_folder([input.model]),
            out=job_out("export", wc),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("export"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule view:
    input:
        ply=stage_file("static", "canonical"),
        model=final_model,
        views=stage_file("views", "views"),
    output:
        report(
            directory(stage_out("view")),
            htmlindex=layout_name("view", "index"),
            caption="../report/viewer.rst",
            category="Viewer",
            subcategory="{scene} {variant}",
        ),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/view.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/view.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        cmd=lambda wc, input, output: stage_command(
            "view",
            jparams("view")(wc),
            out=output[0],
            model=_folder([input.model]),
            static=stage_dir(wc.scene, "static"),
            views=stage_dir(wc.scene, "views"),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("view"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
