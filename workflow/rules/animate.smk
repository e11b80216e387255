# Stages 6-8, unrolled into rounds (see anigs/animate/plan.py): round r renders every view of its
# dataset with the model of round r-1 (round 0 = static canonical), refines each view, then trains
# one model (fan-in). round_jobs (common.smk) picks how the work is split:
# - view: render_clip and refine jobs per view (fan-out: independent GPU jobs on a cluster), then
#   an update job;
# - round: one `round` job per round writes the same files into round{r}/render, round{r}/target
#   and round{r}/model.pt (anigs round ... --then update ...: one Python and torch start-up).


rule render_clip:
    input:
        ply=stage_path("static", "canonical.ply"),
        views=stage_path("views", "views.json"),
        model=_render_model,
    output:
        f"{VARIANT_DIR}/round{{round}}/render/{{view}}.npz",
    params:
        p=jparams("render_clip", _frames),
        model=lambda wc, input: f"--model {input.model[0]}" if input.model else "",
        version=ANIGS_VERSION,
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/render_clip_{{view}}.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/render_clip_{{view}}.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} render_clip --canonical {input.ply:q} {params.model} --view-json {input.views:q} "
        "--view-id {wildcards.view} --out {output:q} --params {params.p:q} > {log} 2>&1"


rule refine:
    input:
        clip=f"{VARIANT_DIR}/round{{round}}/render/{{view}}.npz",
        masks=stage_path("masks"),
        effects=_effects_json,
    output:
        f"{VARIANT_DIR}/round{{round}}/target/{{view}}.npz",
    params:
        p=jparams("refine", _refine_extra),
        effects=lambda wc, input: f"--effects-json {input.effects}" if input.effects else "",
        version=ANIGS_VERSION,
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/refine_{{view}}.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/refine_{{view}}.tsv"
    threads: 1
    resources:
        mem_mb=6000,
        runtime=60,
        gpu=lambda wc: wants_gpu(wc.scene, wc.variant),
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} refine --clip {input.clip:q} --mask {input.masks}/{wildcards.view}.png "
        "--round {wildcards.round} --view {wildcards.view} {params.effects} --out {output:q} --params {params.p:q} > {log} 2>&1"


rule round:
    input:
        ply=stage_path("static", "canonical.ply"),
        views=stage_path("views", "views.json"),
        model=_render_model,
        masks=stage_path("masks"),
        effects=_effects_json,
        earlier=_earlier_targets,
        init=_init_model,
    output:
        render=directory(f"{VARIANT_DIR}/round{{round}}/render"),
        target=directory(f"{VARIANT_DIR}/round{{round}}/target"),
        model=f"{VARIANT_DIR}/round{{round}}/model.pt",
        log_json=f"{VARIANT_DIR}/round{{round}}/update.json",
    params:
        views=lambda wc: ",".join(round_views(wc.scene, wc.variant, int(wc.round))),
        render=jparams("render_clip", _frames),
        refine=jparams("refine", _refine_extra),
        model=lambda wc, input: f"--model {input.model[0]}" if input.model else "",
        effects=lambda wc, input: f"--effects-json {input.effects}" if input.effects else "",
        p=jparams("update", _update_extra),
        init=lambda wc, input: f"--init-model {input.init[0]}" if input.init else "",
        method=_method_args,
        contain=_contain_args,
        targets=_target_files,
        version=ANIGS_VERSION,
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/round.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/round.tsv"
    threads: 2  # the round's views one after another, each with both threads (same files as 1 thread)
    resources:
        mem_mb=8000,
        runtime=180,
        gpu=lambda wc: wants_gpu(wc.scene, wc.variant),
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} round --canonical {input.ply:q} {params.model} --view-json {input.views:q} "
        "--views {params.views} --masks-dir {input.masks:q} --round {wildcards.round} {params.effects} "
        "--render-dir {output.render:q} --target-dir {output.target:q} "
        "--render-params {params.render:q} --refine-params {params.refine:q} "
        "--then update --canonical {input.ply:q} {params.init} --targets {params.targets} "
        "--view-json {input.views:q} --dynamic {input.masks}/dynamic.npy --effect-labels {input.masks}/effect_labels.npy "
        "{params.contain} --out {output.model:q} --log-json {output.log_json:q} --params {params.p:q} {params.method} "
        "> {log} 2>&1"


# One model per round: the round job above trains it in the same process (round_jobs: round), or
# this job after the per-view jobs (round_jobs: view).
if ROUND_JOBS == "round":

    ruleorder: round > update

else:

    ruleorder: update > round


rule update:
    input:
        ply=stage_path("static", "canonical.ply"),
        views=stage_path("views", "views.json"),
        masks=stage_path("masks"),
        targets=_targets,
        init=_init_model,
    output:
        model=f"{VARIANT_DIR}/round{{round}}/model.pt",
        log_json=f"{VARIANT_DIR}/round{{round}}/update.json",
    params:
        p=jparams("update", _update_extra),
        init=lambda wc, input: f"--init-model {input.init[0]}" if input.init else "",
        method=_method_args,
        contain=_contain_args,
        targets=_target_files,
        version=ANIGS_VERSION,
    log:
        f"{VARIANT_DIR}/logs/round{{round}}/update.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/round{{round}}/update.tsv"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=120,
        gpu=lambda wc: int(str(config["device"]).startswith("cuda")),
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} update --canonical {input.ply:q} {params.init} --targets {params.targets} "
        "--view-json {input.views:q} --dynamic {input.masks}/dynamic.npy --effect-labels {input.masks}/effect_labels.npy {params.contain} --out {output.model:q} "
        "--log-json {output.log_json:q} --params {params.p:q} {params.method} > {log} 2>&1"


# Nothing to animate (the effects stage chose no effect): one cheap job writes a model in which
# nothing moves, and the final renders, export, viewer and evaluation use it; no round runs.
rule still:
    input:
        ply=stage_path("static", "canonical.ply"),
        effects=stage_path("effects", "effects.json"),
    output:
        f"{VARIANT_DIR}/still/model.pt",
    params:
        p=jparams("update", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        frames=lambda wc: sec(wc.scene, "animate", wc.variant)["frames"],
        reason=_still_reason,
        version=ANIGS_VERSION,
    log:
        f"{VARIANT_DIR}/logs/still.log",
    benchmark:
        f"{VARIANT_DIR}/benchmarks/still.tsv"
    threads: 1
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} update --canonical {input.ply:q} --still {params.reason:q} --frames {params.frames} "
        "--out {output:q} --params {params.p:q} > {log} 2>&1"
