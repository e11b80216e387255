# The named targets' files: `all_<stage>` (Snakefile) asks for what the jobs of one stage of the
# registry (anigs/registry.py STAGES) write, for every scene and variant of the config.
from anigs.registry import BY_NAME as STAGE_BY_NAME


def _stage_patterns(stage, scene):
    """The output patterns of the jobs that run ``stage`` for ``scene`` (``{variant}``, ``{round}``
    and ``{view}`` left in): its rule's outputs, or those of its rule for the scene's source
    (``capture_synthetic``, ``capture_photos``). With ``round_jobs: round`` the round job writes the
    render_clip and refine stages' files, as one folder per round."""
    if ROUND_JOBS == "round" and stage in ("render_clip", "refine"):
        return [stage_out(stage, "clips" if stage == "render_clip" else "targets")]
    if stage == "round" and ROUND_JOBS != "round":
        raise ValueError(
            "all_round: the round stage runs only with round_jobs: round (now "
            f"{ROUND_JOBS!r}); all_render_clip, all_refine and all_update name the per-view jobs' files"
        )
    source = ALL_SCENES[scene]["source"]
    if source == "colmap" and stage in ("capture", "sfm"):
        # a COLMAP project is not captured; its sfm folder is the colmap_import job's
        return [] if stage == "capture" else [str(o) for o in rules.colmap_import.output]
    name = stage if rules.has(stage) else f"{stage}_{source}"
    return [str(o) for o in getattr(rules, name).output]


def _rounds(scene, variant):
    """Rounds 1..n of (scene, variant); none when the effects stage chose nothing to animate."""
    return range(1, plan(scene, variant).num_rounds + 1) if animates(scene) else range(0)


def _fill(patterns, scene, variant):
    """``patterns`` for one (scene, variant): a ``{round}`` pattern once per round, a ``{view}`` one
    once per view whose clip that round makes (:meth:`RoundFiles.clip_views`)."""
    out = []
    for p in patterns:
        if "{round}" not in p:
            out.append(p.format(scene=scene, variant=variant))
            continue
        for r in _rounds(scene, variant):
            views = rounds(scene, variant).clip_views(r) if "{view}" in p else [None]
            out += [p.format(scene=scene, variant=variant, round=r, view=v) for v in views]
    return out


def stage_targets(stage):
    """Every file the ``stage`` jobs write for the config's scenes (and variants): ``animate``, the
    round plan, is every variant's final model; the update stage's, a still model where nothing moves;
    fvd_gt's, the synthetic scenes'."""
    scope = STAGE_BY_NAME[stage].scope
    if scope == "global":
        return [str(o) for o in getattr(rules, stage).output]
    variants = config["variants"] if scope == "variant" else [None]
    out = []
    for s in SCENES:
        if stage == "fvd_gt" and not is_synthetic(s):
            continue  # FVD-GT compares with a synthetic scene's ground-truth motion
        for v in variants:
            if stage == "animate":
                out.append(final_model_of(s, v))
            elif stage == "update" and not animates(s):
                out.append(still_model(s, v))
            else:
                out += _fill(_stage_patterns(stage, s), s, v)
    return out


def targets_of(stage):
    """The input function of ``all_<stage>``."""
    return lambda wc: stage_targets(stage)
