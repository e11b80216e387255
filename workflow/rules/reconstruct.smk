# Stages 2-3: COLMAP structure from motion (or the user's COLMAP project, imported), then the static
# (canonical) 3DGS fit (or a splat trained elsewhere, imported and checked against the photos).


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
        tracks=stage_out("sfm", "tracks"),
        report=report(stage_out("sfm", "report"), caption="../report/sfm.rst", category="Structure from motion"),
    log:
        f"{R}/{{scene}}/logs/sfm.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/sfm.tsv"
    wildcard_constraints:
        scene=SFM_SCENES,
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=60,
    params:
        cmd=lambda wc, input: stage_command(
            "sfm",
            jparams("sfm")(wc),
            images=input.images,
            out=job_out("sfm", wc),
            gt_cameras=gt_of(wc.scene, "gt_cameras") if is_synthetic(wc.scene) else None,
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("sfm"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


# source: colmap: the user's own cameras; no capture job, no feature extraction, matching or mapping.
# The sfm stage reads the model (binary or text), undistorts it when its camera model has distortion and
# writes the same folder as for photos (cameras, points, tracks, report with the images it leaves out).
rule colmap_import:
    input:
        images=lambda wc: ALL_SCENES[wc.scene]["images"],
        sparse=lambda wc: ALL_SCENES[wc.scene]["sparse"],
    output:
        images=directory(stage_out("sfm", "images")),
        sparse=directory(stage_out("sfm", "sparse")),
        cameras=stage_out("sfm", "cameras"),
        points=stage_out("sfm", "points"),
        tracks=stage_out("sfm", "tracks"),
        report=stage_out("sfm", "report"),
    log:
        f"{R}/{{scene}}/logs/sfm.log",
    benchmark:
        f"{R}/{{scene}}/benchmarks/sfm.tsv"
    wildcard_constraints:
        scene=COLMAP_SCENES,
    conda:
        "../../envs/anigs.yaml"
    threads: 2
    resources:
        mem_mb=8000,
        runtime=30,
    params:
        cmd=lambda wc, input: stage_command(
            "sfm", jparams("sfm")(wc), images=input.images, model=input.sparse, out=job_out("sfm", wc)
        ),
        p=jparams("sfm"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"


rule static:
    input:
        images=stage_file("sfm", "images"),
        cameras=stage_file("sfm", "cameras"),
        points=stage_file("sfm", "points"),
        # photos: the SfM points each photo observes, for the depth loss (a synthetic scene fits without it)
        tracks=lambda wc: [] if is_synthetic(wc.scene) else [stage_file_of(wc.scene, "sfm", "tracks")],
        # a splat trained elsewhere (scene `splat:`): imported instead of fitted, in the frame its trainer's
        # files (or the sfm report's normalisation of the COLMAP project) give
        splat=lambda wc: [splat_of(wc.scene)] if splat_of(wc.scene) else [],
        report=lambda wc: [stage_file_of(wc.scene, "sfm", "report")] if splat_of(wc.scene) else [],
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
        cmd=lambda wc, input: stage_command(
            "static",
            jparams("static")(wc),
            images=input.images,
            cameras=input.cameras,
            points=input.points,
            tracks=None if is_synthetic(wc.scene) else stage_file_of(wc.scene, "sfm", "tracks"),
            out=job_out("static", wc),
            no_progress=True,
            splat=splat_of(wc.scene),
            report=stage_file_of(wc.scene, "sfm", "report") if splat_of(wc.scene) else None,
        ),
        # the config the command uses, as wildcard-only params: Snakemake records these (not the input-dependent cmd)
        p=jparams("static"),
        version=ANIGS_VERSION,
    shell:
        "anigs --threads {threads} {params.cmd} > {log} 2>&1"
