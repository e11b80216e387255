# Stage 10: evaluation per (scene, variant) and the paper's tables.


rule eval_scene:
    input:
        final=f"{R}/{{scene}}/{{variant}}/final/final.json",
        masks=stage_path("masks"),
        ply=stage_path("static", "canonical.ply"),
        model=final_model,
        cameras=stage_path("sfm", "cameras.json"),
        points=stage_path("sfm", "points.npz"),
        images=stage_path("capture", "images"),
    output:
        report(f"{R}/{{scene}}/{{variant}}/eval/metrics.json", caption="../report/metrics.rst", category="Metrics",
               subcategory="{scene} {variant}"),
    params:
        p=jparams("eval", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        final=lambda wc: f"{R}/{wc.scene}/{wc.variant}/final/clips",
        gt=_eval_gt,
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/{{variant}}/logs/eval.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/eval.tsv"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=60,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} eval --final-dir {params.final:q} --masks {input.masks:q} --model {input.model:q} "
        "--canonical {input.ply:q} --cameras {input.cameras:q} --images {input.images:q} --points {input.points:q} "
        "{params.gt} --scene {wildcards.scene} --variant {wildcards.variant} --out {output:q} "
        "--params {params.p:q} > {log} 2>&1"


rule tables_build:
    input:
        [f"{R}/{s}/{v}/eval/metrics.json" for s in SCENES for v in config["table_variants"]],
    output:
        f"{R}/tables/tables.json",
    params:
        out=lambda wc, output: os.path.dirname(output[0]),
        version=ANIGS_VERSION,
    log:
        f"{R}/logs/tables.log",
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs tables --metrics {input} --out {params.out:q} > {log} 2>&1"


def _tradeoff_metrics(wc):
    return [f"{R}/{p.scene(wc.scene)}/{p.variant}/eval/metrics.json" for p in TRADEOFF[wc.scene]]


def _tradeoff_points(wc):
    return json.dumps([{"variant": p.variant, "knob": p.knob, "value": p.value, "scene_tag": p.scene_tag}
                       for p in TRADEOFF[wc.scene]])


rule tradeoff_report:
    input:
        _tradeoff_metrics,
    output:
        csv=report(f"{R}/tradeoff/{{scene}}.csv", caption="../report/tradeoff.rst", category="Accuracy versus time"),
        plots=[report(f"{R}/tradeoff/{{scene}}_{knob_filename(k)}.png", caption="../report/tradeoff.rst",
                      category="Accuracy versus time") for k, v in config.get("tradeoff", {}).get("knobs", {}).items() if v],
    params:
        points=_tradeoff_points,
        metrics=lambda wc: " ".join(config.get("tradeoff", {}).get("plot_metrics", [])),
        version=ANIGS_VERSION,
    log:
        f"{R}/logs/tradeoff_{{scene}}.log",
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs tradeoff --scene {wildcards.scene} --results {R:q} --points {params.points:q} "
        "--out-csv {output.csv:q} --plot-metrics {params.metrics} > {log} 2>&1"
