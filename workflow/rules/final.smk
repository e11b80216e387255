# Stage 9: final renders (videos, slices) and exports of the last round's model.


rule final:
    input:
        ply=stage_path("static", "canonical.ply"),
        model=final_model,
        views=stage_path("views", "views.json"),
        cameras=stage_path("sfm", "cameras.json"),
        masks=stage_path("masks"),
    output:
        summary=f"{R}/{{scene}}/{{variant}}/final/final.json",
        slices=report(directory(f"{R}/{{scene}}/{{variant}}/final/slices"), patterns=["{name}.png"],
                      caption="../report/slices.rst", category="Space-time slices", subcategory="{scene} {variant}"),
        path=report(f"{R}/{{scene}}/{{variant}}/final/path.mp4", caption="../report/final.rst", category="Videos",
                    subcategory="{scene} {variant}"),
        clip_metrics=f"{R}/{{scene}}/{{variant}}/eval/clip_metrics.json",
    params:
        p=jparams("final", lambda wc: {"device": config["device"]}),
        out=lambda wc: f"{R}/{wc.scene}/{wc.variant}/final",
        ep=jparams("eval", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        method=_eval_method,
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/{{variant}}/logs/final.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/final.tsv"
    threads: 1  # mostly single-threaded Python and video encoding: the model's metrics run beside it
    resources:
        mem_mb=8000,
        runtime=60,
    conda:
        "../../envs/anigs.yaml"
    # the final clips' metrics (the eval stage's clips half) in the same process: one start-up less
    shell:
        "anigs --threads {threads} final --canonical {input.ply:q} --model {input.model:q} --views {input.views:q} "
        "--cameras {input.cameras:q} --masks {input.masks:q} --out {params.out:q} --params {params.p:q} "
        "--then eval --part clips --final-dir {params.out:q}/clips --masks {input.masks:q} --model {input.model:q} "
        "--canonical {input.ply:q} --cameras {input.cameras:q} --scene {wildcards.scene} {params.method} "
        "--out {output.clip_metrics:q} --params {params.ep:q} > {log} 2>&1"


rule export:
    input:
        ply=stage_path("static", "canonical.ply"),
        model=final_model,
    output:
        sidecar=f"{R}/{{scene}}/{{variant}}/export/animated.json",
        ply=f"{R}/{{scene}}/{{variant}}/export/animated.ply",
        compact=f"{R}/{{scene}}/{{variant}}/export/scene.anigs",
    params:
        p=jparams("export"),
        out=lambda wc: f"{R}/{wc.scene}/{wc.variant}/export",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/{{variant}}/logs/export.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/export.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} export --canonical {input.ply:q} --model {input.model:q} --out {params.out:q} "
        "--params {params.p:q} > {log} 2>&1"


rule view:
    input:
        ply=stage_path("static", "canonical.ply"),
        model=final_model,
        views=stage_path("views", "views.json"),
    output:
        report(directory(f"{R}/{{scene}}/{{variant}}/viewer"), htmlindex="index.html", caption="../report/viewer.rst",
               category="Viewer", subcategory="{scene} {variant}"),
    params:
        p=jparams("view"),
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/{{variant}}/logs/view.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/view.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs view --model {input.model:q} --canonical {input.ply:q} --views {input.views:q} --out {output:q} "
        "--params {params.p:q} > {log} 2>&1"
