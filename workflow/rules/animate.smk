# Stages 6-8, unrolled into rounds (see anigs/animate/plan.py): round r renders every view of its
# dataset with the model of round r-1 (round 0 = static canonical), refines each view, then trains
# one model (fan-in). round_jobs (common.smk) picks how the work is split:
# - view: render_clip and refine jobs per view (fan-out: independent GPU jobs on a cluster), then
#   an update job;
# - round: one `round` job per round writes the same files into round{r}/render, round{r}/target
#   and round{r}/model.pt: the round stage's command, then the update rule's own command
#   (anigs round ... --then update ...: one Python and torch start-up).


rule render_clip:
    input:
        ply=stage_file("static", "canonical"),
        views=stage_file("views", "views"),
        model=round_files("render_model"),
    output:
        stage_out("render_clip", "clip"),
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/render_clip_{{view}}.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/render_clip_{{view}}.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=20,
    params:
        cmd=lambda wc, input: stage_command(
            "render_clip",
            jparams("render_clip", _frames)(wc),
            static=stage_dir(wc.scene, "static"),
            out=round_folder(R, wc.scene, wc.variant, wc.round),
            model=_folder(input.model),
            views=stage_dir(wc.scene, "views"),
            view_id=wc.view,
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("render_clip", _frames),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule refine:
    input:
        clip=stage_out("render_clip", "clip"),
        masks=stage_folder("masks"),
        effects=_effects_json,
        weights=lambda wc: refine_weights(sec(wc.scene, "refine", wc.variant)),
    output:
        stage_out("refine", "target"),
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/refine_{{view}}.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/refine_{{view}}.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=6000,
        runtime=60,
        gpu=lambda wc: wants_gpu(wc.scene, wc.variant),
    params:
        cmd=lambda wc, input: stage_command(
            "refine",
            jparams("refine", _refine_extra)(wc),
            render_clip=round_folder(R, wc.scene, wc.variant, wc.round),
            view=wc.view,
            out=round_folder(R, wc.scene, wc.variant, wc.round),
            masks=stage_dir(wc.scene, "masks"),
            effects=_folder(input.effects),
            round=int(wc.round),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("refine", _refine_extra),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule round:
    input:
        ply=stage_file("static", "canonical"),
        views=stage_file("views", "views"),
        model=round_files("render_model"),
        masks=stage_folder("masks"),
        effects=_effects_json,
        earlier=round_files("earlier_targets"),
        init=round_files("init_model"),
    output:
        render=directory(stage_out("render_clip", "clips")),
        target=directory(stage_out("refine", "targets")),
        model=stage_out("update", "model"),
        log_json=stage_out("update", "log"),
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/round.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/round.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2  # the round's views one after another, each with both threads (same files as 1 thread)
    resources:
        mem_mb=8000,
        runtime=180,
        gpu=lambda wc: wants_gpu(wc.scene, wc.variant),
    params:
        # the round's render and refine work in one process, then its update
        cmd=lambda wc, input: stage_command(
            "round",
            static=stage_dir(wc.scene, "static"),
            views=stage_dir(wc.scene, "views"),
            masks=stage_dir(wc.scene, "masks"),
            view_ids=rounds(wc.scene, wc.variant).clip_views(int(wc.round)),
            round=int(wc.round),
            out=round_folder(R, wc.scene, wc.variant, wc.round),
            model=_folder(input.model),
            effects=_folder(input.effects),
            render_params=jparams("render_clip", _frames)(wc),
            refine_params=jparams("refine", _refine_extra)(wc),
        )
        + f" --then {update_command(wc, input)}",
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        render=jparams("render_clip", _frames),
        refine=jparams("refine", _refine_extra),
        up=jparams("update", _update_extra),
        animate=jparams("animate"),
        views=lambda wc: ",".join(rounds(wc.scene, wc.variant).clip_views(int(wc.round))),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# One model per round: the round job above trains it in the same process (round_jobs: round), or
# this job after the per-view jobs (round_jobs: view).
if ROUND_JOBS == "round":

    ruleorder: round > update

else:

    ruleorder: update > round


rule update:
    input:
        ply=stage_file("static", "canonical"),
        views=stage_file("views", "views"),
        masks=stage_folder("masks"),
        targets=round_files("targets"),
        init=round_files("init_model"),
    output:
        model=stage_out("update", "model"),
        log_json=stage_out("update", "log"),
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/update.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/update.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=120,
        gpu=lambda wc: int(str(config["device"]).startswith("cuda")),
    params:
        cmd=update_command,
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("update", _update_extra),
        animate=jparams("animate"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# Nothing to animate (the effects stage chose no effect): one cheap job writes a model in which
# nothing moves, and the final renders, export, viewer and evaluation use it; no round runs.
rule still:
    input:
        ply=stage_file("static", "canonical"),
        effects=stage_file("effects", "effects"),
    output:
        still_model(),
    log:
        f"{VARIANT_DIR}/logs/still.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/still.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    params:
        cmd=lambda wc, output: stage_command(
            "update",
            jparams("update")(wc),
            static=stage_dir(wc.scene, "static"),
            out=os.path.dirname(output[0]),
            still=_still_reason(wc),
            frames=sec(wc.scene, "animate", wc.variant)["frames"],
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("update"),
        frames=lambda wc: sec(wc.scene, "animate", wc.variant)["frames"],
        reason=_still_reason,
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
