# Stage 10: evaluation per (scene, variant) and the paper's tables.


# The evaluation in two halves: the model's metrics (ground-truth motion, the multiview protocol's
# two static fits) need the model, not the final clips: one thread, beside the final renders; the
# final clips' metrics run in the final job (final.smk); the eval rule merges them.
rule eval_model:
    input:
        ply=stage_file("static", "canonical"),
        model=final_model,
        cameras=stage_file("sfm", "cameras"),
        points=stage_file("sfm", "points"),
        images=stage_file("sfm", "images"),  # undistorted: the images the sfm cameras describe
    output:
        stage_out("eval", "model_metrics"),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/eval_model.log",
    benchmark:
        f"{R}/{{scene}}/{{variant}}/benchmarks/eval_model.tsv"
    priority: 1  # the longest job after the last update: start it first, beside the final renders
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=8000,
        runtime=60,
    params:
        cmd=lambda wc, input: eval_command(
            wc,
            "model",
            model=_folder([input.model]),
            static=stage_dir(wc.scene, "static"),
            sfm=stage_dir(wc.scene, "sfm"),
            capture=stage_dir(wc.scene, "capture") if is_synthetic(wc.scene) else None,
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("eval"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# the evaluation: the two halves merged (inside Snakemake: a JSON merge, no process start-up).
rule eval:
    input:
        clips=stage_out("eval", "clip_metrics"),
        model=stage_out("eval", "model_metrics"),
        fvd_gt=lambda wc: _fvd_gt_eval_input(wc),  # fvd_gt.when: always (workflow/rules/fvd_gt.smk)
    output:
        report(
            stage_out("eval", "metrics"),
            caption="../report/metrics.rst",
            category="Metrics",
            subcategory="{scene} {variant}",
        ),
    log:
        f"{R}/{{scene}}/{{variant}}/logs/eval.log",
    params:
        version=ANIGS_VERSION,
    run:
        merge_halves(output[0], input.clips, input.model, input.fvd_gt, log[0])


rule tables:
    input:
        [stage_out("eval", "metrics", scene=s, variant=v) for s in SCENES for v in config["table_variants"]],
        fvd_gt_table_inputs(),  # FVD-GT records (synthetic scenes), joined to their evaluation by anigs tables
    output:
        stage_out("tables", "index"),
    log:
        f"{R}/logs/tables.log",
    conda:
        "../../envs/anigs.yaml"
    params:
        cmd=lambda wc, input, output: stage_command("tables", metrics=list(input), out=os.path.dirname(output[0])),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# one job for every scene's report, so that `snakemake tradeoff` names it
rule tradeoff:
    input:
        _tradeoff_metrics,
    output:
        csv=[
            report(
                stage_out("tradeoff", "csv", scene=s),
                caption="../report/tradeoff.rst",
                category="Accuracy versus time",
            )
            for s in SCENES
        ],
        md=[stage_out("tradeoff", "md", scene=s) for s in SCENES],
        plots=_tradeoff_plots(),
    log:
        f"{R}/logs/tradeoff.log",
    conda:
        "../../envs/anigs.yaml"
    params:
        cmd=lambda wc: stage_command(
            "tradeoff",
            results=R,
            points=points_json(TRADEOFF),
            out=stage_out("tradeoff"),
            plot_metrics=list(config.get("tradeoff", {}).get("plot_metrics", [])),
        ),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# The 2AFC user study page (paper Table 4): ours against each baseline, same scene and view, side by
# side. Collect answers with `anigs study serve --dir results/study`; `anigs study tally` makes Table 4.
rule study:
    input:
        [stage_out("final", "summary", scene=s, variant=v) for s in SCENES for v in ["full", *_study_variants()]],
    output:
        stage_out(STUDY, "manifest"),
    log:
        f"{R}/logs/study.log",
    conda:
        "../../envs/anigs.yaml"
    params:
        scenes=" ".join(SCENES),
        others=lambda wc: " ".join(_study_variants()),
        labels=lambda wc: " ".join(
            f"--label {v}={METHODS[method_of(next(iter(SCENES)), v)]}" for v in _study_variants()
        ),
        seed=config["seed"],
        results=lambda wc, output: os.path.dirname(os.path.dirname(output[0])),
        out=lambda wc, output: os.path.dirname(output[0]),  # the study folder (its manifest is at the top)
        version=ANIGS_VERSION,
    shell:
        "anigs study build --results {params.results:q} --scenes {params.scenes} --ours full --others {params.others} "
        "{params.labels} --catch-trials 2 --seed {params.seed} --out {params.out:q} > {log} 2>&1"
