# Stage 1: the capture. Synthetic scenes are rendered (with ground truth); photo scenes are
# imported (EXIF orientation, optional downscale, unreadable files reported).


rule capture_synthetic:
    output:
        images=directory(f"{R}/{{scene}}/capture/images"),
        summary=f"{R}/{{scene}}/capture/capture.json",
        gt_cameras=f"{R}/{{scene}}/capture/gt/cameras.json",
        gt_gaussians=f"{R}/{{scene}}/capture/gt/gaussians.ply",
        gt_labels=f"{R}/{{scene}}/capture/gt/labels.npy",
        gt_motion=f"{R}/{{scene}}/capture/gt/motion.json",
    wildcard_constraints:
        scene=SYNTH_SCENES,
    params:
        p=lambda wc: json.dumps(SCENES[wc.scene]["synthetic"] or {}, sort_keys=True),
        out=lambda wc: f"{R}/{wc.scene}/capture",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/capture.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/capture.tsv"
    threads: 2
    resources:
        mem_mb=4000,
        runtime=20,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs --threads {threads} capture --source synthetic --params {params.p:q} --out {params.out:q} > {log} 2>&1"


rule capture_photos:
    output:
        images=directory(f"{R}/{{scene}}/capture/images"),
        summary=f"{R}/{{scene}}/capture/capture.json",
    wildcard_constraints:
        scene=PHOTO_SCENES,
    params:
        p=jparams("capture"),
        photos=lambda wc: SCENES[wc.scene]["photos"],
        out=lambda wc: f"{R}/{wc.scene}/capture",
        version=ANIGS_VERSION,
    log:
        f"{R}/{{scene}}/logs/capture.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/capture.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=30,
    conda:
        "../../envs/anigs.yaml"
    shell:
        "anigs capture --source photos --photos {params.photos:q} --params {params.p:q} --out {params.out:q} > {log} 2>&1"
