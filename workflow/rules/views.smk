# Stages 4-6: the effects the scene contains (its region of interest), the view queue
# (incremental viewpoint expansion) and dynamic masks per view.


checkpoint effects:
    input:
        ply=stage_path("static", "canonical.ply"),
        cameras=stage_path("sfm", "cameras.json"),
        images=stage_path("sfm", "images"),  # undistorted: the images sfm/cameras.json describes
        selections=lambda wc: [s["ply"] for s in sec(wc.scene, "effects")["selections"] if "ply" in s],  # SuperSplat exports
    output:
        effects=f"{R}/{{scene}}/effects/effects.json",
        regions=f"{R}/{{scene}}/effects/regions.npy",
        dynamic=f"{R}/{{scene}}/effects/dynamic.npy",
        overview=report(f"{R}/{{scene}}/effects/overview.png", caption="../report/effects.rst", category="Effects"),
    params:
        p=jparams("effects", _effects_prompt),
        out=lambda wc: f"{R}/{wc.scene}/effects",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/effects.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/effects.tsv"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} effects --canonical {input.ply:q} --cameras {input.cameras:q} "
        "--images {input.images:q} --out {params.out:q} --params {params.p:q} > {log} 2>&1"


# a checkpoint: the queue's length (views with a negligible dynamic region are left out) sets the rounds
checkpoint views:
    input:
        ply=stage_path("static", "canonical.ply"),
        cameras=stage_path("sfm", "cameras.json"),
        points=stage_path("sfm", "points.npz"),  # the content test: sharp Gaussians lie near SfM points
        roi=_roi_inputs,
        gt=_gt_inputs,
    output:
        views=f"{R}/{{scene}}/views/views.json",
        topdown=report(f"{R}/{{scene}}/views/topdown.png", caption="../report/views.rst", category="Views"),
    params:
        p=jparams("views"),
        roi=_roi_args,
        out=lambda wc: f"{R}/{wc.scene}/views",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/views.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/views.tsv"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} views --canonical {input.ply:q} --cameras {input.cameras:q} "
        "--points {input.points:q} {params.roi} "
        "--out {params.out:q} --params {params.p:q} > {log} 2>&1"


rule masks:
    input:
        ply=stage_path("static", "canonical.ply"),
        views=stage_path("views", "views.json"),
        # the capture photos are segmented too: the lift to 3D votes over them and the queued views
        images=stage_path("sfm", "images"),
        cameras=stage_path("sfm", "cameras.json"),
        effects=stage_path("effects", "effects.json"),
        gt=_gt_inputs,
    output:
        # {view}.png, {view}_overlay.png (+ per-effect masks), dynamic.npy, masks.json
        masks=report(directory(f"{R}/{{scene}}/masks"), patterns=["{name}_overlay.png"],
                     caption="../report/masks.rst", category="Masks", subcategory="{scene}"),
    params:
        p=jparams("masks"),
        effects=lambda wc: stage_dir(wc.scene, "effects"),
        gt=_mask_gt_args,
        out=lambda wc: f"{R}/{wc.scene}/masks",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/masks.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/masks.tsv"
    threads: 2  # the rasterizer's loops use both; the same files as with 1 thread
    resources:
        mem_mb=4000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} masks --canonical {input.ply:q} --views {input.views:q} "
        "--images {input.images:q} --cameras {input.cameras:q} --effects {params.effects:q} {params.gt} "
        "--out {params.out:q} --params {params.p:q} > {log} 2>&1"
