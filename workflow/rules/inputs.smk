# Input and parameter functions of the views, fvd_gt, eval, tradeoff and study rules (kept apart from
# the rules: `snakemake --lint` wants a snakefile to hold rules or functions, not both).


# ---- views.smk ----


def _roi_inputs(wc):
    return [] if is_synthetic(wc.scene) else [stage_file_of(wc.scene, "effects", "dynamic")]


# ---- fvd_gt.smk ----


def fvd_gt_wanted(scene, variant="full", target="tables"):
    """Whether FVD-GT runs for (scene, variant) when ``target`` (tables | eval) is built (fvd_gt.wanted)."""
    return fvd_gt_runs(is_synthetic(scene), sec(scene, "fvd_gt", variant)["when"], target)


def _fvd_gt_eval_input(wc):
    """eval: the FVD-GT record joins the merged metrics with fvd_gt.when: always."""
    if not fvd_gt_wanted(wc.scene, wc.variant, "eval"):
        return []
    return [job_out("fvd_gt", wc, "record")]


def fvd_gt_table_inputs():
    return [
        stage_out("fvd_gt", "record", scene=s, variant=v)
        for s in SCENES
        for v in config["table_variants"]
        if fvd_gt_wanted(s, v)
    ]


def _fvd_gt_scene(wc):
    """The fvd_gt stage's scene inputs (the capture's ground truth, the reconstruction's frame and
    canonical scene) and the eval section (its I3D network)."""
    return {
        "capture": stage_dir(wc.scene, "capture"),
        "sfm": stage_dir(wc.scene, "sfm"),
        "static": stage_dir(wc.scene, "static"),
        "eval_params": jparams("eval")(wc),
    }


# ---- eval.smk ----


def _tradeoff_metrics(wc):
    return [
        stage_out("eval", "metrics", scene=p.scene(s), variant=p.variant)
        for s, pts in tradeoff_points().items()
        for p in pts
    ]


def _tradeoff_plots():
    plot = report  # (a line starting with `report(` would parse as the rule keyword)
    files = plot_files(R, list(SCENES), swept_knobs(config.get("tradeoff", {})))
    return [plot(f, caption="../report/tradeoff.rst", category="Accuracy versus time") for f in files]


def _study_variants():
    """The compared variants of the 2AFC study: the baselines among table_variants (paper Table 4)."""
    return [v for v in config["table_variants"] if v != "full" and method_of(next(iter(SCENES)), v) != "anigs"]
