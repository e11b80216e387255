# Stage 1: the capture. Synthetic scenes are rendered (with ground truth); photo scenes are
# imported (EXIF orientation, optional downscale, unreadable files reported).


rule capture_synthetic:
    output:
        images=directory(stage_out("capture", "images")),
        summary=stage_out("capture", "summary"),
        gt_cameras=stage_out("capture", "gt_cameras"),
        gt_gaussians=stage_out("capture", "gt_gaussians"),
        gt_labels=stage_out("capture", "gt_labels"),
        gt_anchors=stage_out("capture", "gt_anchors"),
        gt_motion=stage_out("capture", "gt_motion"),
    log:
        f"{R}/{{scene}}/logs/capture.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/capture.tsv"
    wildcard_constraints:
        scene=SYNTH_SCENES,
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=4000,
        runtime=20,
    params:
        cmd=lambda wc: stage_command(
            "capture",
            json.dumps(SCENES[wc.scene]["synthetic"] or {}, sort_keys=True),
            out=job_out("capture", wc),
            source="synthetic",
        ),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule capture_photos:
    output:
        images=directory(stage_out("capture", "images")),
        summary=stage_out("capture", "summary"),
    log:
        f"{R}/{{scene}}/logs/capture.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/capture.tsv"
    wildcard_constraints:
        scene=PHOTO_SCENES,
    conda:
        "../../envs/anigs.yaml"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    params:
        cmd=lambda wc: stage_command(
            "capture",
            jparams("capture")(wc),
            out=job_out("capture", wc),
            source="photos",
            photos=SCENES[wc.scene]["photos"],
        ),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
