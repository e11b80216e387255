# Stages 4-6: the effects the scene contains (its region of interest), the view queue
# (incremental viewpoint expansion) and dynamic masks per view.


checkpoint effects:
    input:
        ply=stage_file("static", "canonical"),
        fit=stage_file("static", "metrics"),  # the fit's too-blurry warning (--static)
        cameras=stage_file("sfm", "cameras"),
        images=stage_file("sfm", "images"),  # undistorted: the images the sfm cameras describe
        selections=lambda wc: [s["ply"] for s in sec(wc.scene, "effects")["selections"] if "ply" in s],  # SuperSplat exports
        weights=lambda wc: effects_weights(sec(wc.scene, "effects")),  # a changed weight file re-runs the job
    output:
        effects=stage_out("effects", "effects"),
        regions=stage_out("effects", "regions"),
        dynamic=stage_out("effects", "dynamic"),
        overview=report(stage_out("effects", "overview"), caption="../report/effects.rst", category="Effects"),
    log:
        f"{R}/{{scene}}/logs/effects.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/effects.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=30,
    params:
        cmd=lambda wc, input: stage_command(
            "effects",
            jparams("effects", _effects_prompt)(wc),
            canonical=input.ply,
            cameras=input.cameras,
            images=input.images,
            out=job_out("effects", wc),
            static=stage_dir(wc.scene, "static"),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("effects", _effects_prompt),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# a checkpoint: the queue's length (views with a negligible dynamic region are left out) sets the rounds
checkpoint views:
    input:
        ply=stage_file("static", "canonical"),
        cameras=stage_file("sfm", "cameras"),
        points=stage_file("sfm", "points"),  # the content test: sharp Gaussians lie near SfM points
        images=stage_file("sfm", "images"),  # the moving region's sharpness against the photos'
        roi=_roi_inputs,
        gt=gt_inputs,
    output:
        views=stage_out("views", "views"),
        topdown=report(stage_out("views", "topdown"), caption="../report/views.rst", category="Views"),
    log:
        f"{R}/{{scene}}/logs/views.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/views.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        # the region of interest: ground-truth labels on synthetic scenes, else the effects stage's
        cmd=lambda wc, input: stage_command(
            "views",
            jparams("views")(wc),
            canonical=input.ply,
            cameras=input.cameras,
            out=job_out("views", wc),
            effects=None if is_synthetic(wc.scene) else stage_dir(wc.scene, "effects"),
            points=input.points,
            images=input.images,
            **gt_fields(wc.scene),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("views"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule masks:
    input:
        ply=stage_file("static", "canonical"),
        views=stage_file("views", "views"),
        # the capture photos are segmented too: the lift to 3D votes over them and the queued views
        images=stage_file("sfm", "images"),
        cameras=stage_file("sfm", "cameras"),
        effects=stage_file("effects", "effects"),
        gt=gt_inputs,
        weights=lambda wc: masks_weights(sec(wc.scene, "masks")),
    output:
        # the whole folder: a mask (+ overlay, per-effect masks) per queued view, the dynamic set, the
        # report (anigs.stages.masks.Outputs)
        masks=report(
            directory(stage_out("masks")),
            patterns=[layout_name("masks", "overlay").replace("{view}", "{name}")],
            caption="../report/masks.rst",
            category="Masks",
            subcategory="{scene}",
        ),
    log:
        f"{R}/{{scene}}/logs/masks.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/masks.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        cmd=lambda wc, input: stage_command(
            "masks",
            jparams("masks")(wc),
            canonical=input.ply,
            views=stage_dir(wc.scene, "views"),
            out=job_out("masks", wc),
            cameras=input.cameras,
            images=input.images,
            effects=stage_dir(wc.scene, "effects"),
            **gt_fields(wc.scene),
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("masks"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
