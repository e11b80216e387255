# Stages 2-3: COLMAP structure from motion, then the static (canonical) 3DGS fit.


rule sfm:
    input:
        images=f"{R}/{{scene}}/capture/images",
        summary=f"{R}/{{scene}}/capture/capture.json",
        gt=lambda wc: [gt_file(wc.scene, "cameras.json")] if is_synthetic(wc.scene) else [],
    output:
        images=directory(f"{R}/{{scene}}/sfm/images"),  # the images the cameras describe (undistorted)
        sparse=directory(f"{R}/{{scene}}/sfm/sparse"),
        cameras=f"{R}/{{scene}}/sfm/cameras.json",
        points=f"{R}/{{scene}}/sfm/points.npz",
        report=report(f"{R}/{{scene}}/sfm/report.json", caption="../report/sfm.rst",
                      category="Structure from motion"),
    params:
        p=jparams("sfm"),
        out=lambda wc: f"{R}/{wc.scene}/sfm",
        gt=lambda wc: f"--gt-cameras {gt_file(wc.scene, 'cameras.json')}" if is_synthetic(wc.scene) else "",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/sfm.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/sfm.tsv"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=60,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} sfm --images {input.images:q} --out {params.out:q} {params.gt} "
        "--params {params.p:q} > {log} 2>&1"


rule static:
    input:
        images=stage_path("sfm", "images"),
        cameras=stage_path("sfm", "cameras.json"),
        points=stage_path("sfm", "points.npz"),
    output:
        ply=f"{R}/{{scene}}/static/canonical.ply",
        metrics=f"{R}/{{scene}}/static/metrics.json",
    params:
        p=jparams("static", lambda wc: {"device": config["device"], "seed": config["seed"]}),
        out=lambda wc: f"{R}/{wc.scene}/static",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/static.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/static.tsv"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=120,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} static --images {input.images:q} --cameras {input.cameras:q} "
        "--points {input.points:q} --out {params.out:q} --params {params.p:q} --no-progress > {log} 2>&1"
