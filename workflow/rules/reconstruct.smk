# Stages 2-3: COLMAP structure from motion, then the static (canonical) 3DGS fit.


rule sfm:
    input:
        images=stage_out("capture", "images"),
        summary=stage_out("capture", "summary"),
        gt=lambda wc: [gt_of(wc.scene, "gt_cameras")] if is_synthetic(wc.scene) else [],
    output:
        images=directory(stage_out("sfm", "images")),  # the images the cameras describe (undistorted)
        sparse=directory(stage_out("sfm", "sparse")),
        cameras=stage_out("sfm", "cameras"),
        points=stage_out("sfm", "points"),
        report=report(stage_out("sfm", "report"), caption="../report/sfm.rst", category="Structure from motion"),
    log:
        f"{R}/{{scene}}/logs/sfm.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/sfm.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=60,
    params:
        p=jparams("sfm"),
        out=lambda wc: job_out("sfm", wc),
        gt=lambda wc: f"--gt-cameras {gt_of(wc.scene, 'gt_cameras')}" if is_synthetic(wc.scene) else "",
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} sfm --images {input.images:q} --out {params.out:q} {params.gt} "
        "--params {params.p:q} > {log} 2>&1"


rule static:
    input:
        images=stage_file("sfm", "images"),
        cameras=stage_file("sfm", "cameras"),
        points=stage_file("sfm", "points"),
    output:
        ply=stage_out("static", "canonical"),
        metrics=stage_out("static", "metrics"),
        fit=report(
            stage_out("static", "fit"),
            caption="../report/static.rst",
            category="Static fit",
        ),
    log:
        f"{R}/{{scene}}/logs/static.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/static.tsv"
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=120,
    params:
        p=jparams("static", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        out=lambda wc: job_out("static", wc),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} static --images {input.images:q} --cameras {input.cameras:q} "
        "--points {input.points:q} --out {params.out:q} --params {params.p:q} --no-progress > {log} 2>&1"
