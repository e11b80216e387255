"""RoundFiles: the files a round's jobs read, from the round plan and the stages' layouts."""
from __future__ import annotations

from anigs.animate.plan import RoundPlan
from anigs.stages.refine import Outputs as RefineOutputs
from anigs.stages.round_files import RoundFiles
from anigs.stages.update import Outputs as UpdateOutputs


def _files(per_round: bool, dataset_update: bool = True) -> RoundFiles:
    return RoundFiles(RoundPlan(3, dataset_update=dataset_update), "res", "garden", "full", per_round)


def test_folders_and_models_follow_the_update_stage_layout():
    rf = _files(per_round=False)
    assert rf.folder(2) == UpdateOutputs.under("res", scene="garden", variant="full", round=2)
    assert rf.folder("2") == rf.folder(2)  # a wildcard value names the same folder
    assert rf.model(2) == str(UpdateOutputs(rf.folder(2)).path("model"))
    assert rf.render_model(1) == [] and rf.render_model(3) == [rf.model(2)]
    assert rf.init_model(1) == [] and rf.init_model(2) == [rf.model(1)]
    assert rf.final_model() == rf.model(3)


def test_without_dataset_update_each_target_comes_from_its_first_round():
    rf = _files(per_round=False, dataset_update=False)
    assert rf.render_model(3) == []  # every clip is rendered from the static model
    assert rf.clip_views(3) == ["v02"]  # only the view round 3 adds
    want = [str(RefineOutputs(rf.folder(r)).path("target", view=v)) for r, v in ((1, "v00"), (2, "v01"), (3, "v02"))]
    assert rf.target_files(3) == want
    assert rf.targets(3) == want and rf.earlier_targets(3) == []


def test_round_jobs_read_earlier_rounds_folders_but_not_their_own():
    rf = _files(per_round=True, dataset_update=False)
    folders = [str(RefineOutputs(rf.folder(r)).path("targets")) for r in (1, 2, 3)]
    assert rf.targets(3) == sorted(folders)
    assert rf.earlier_targets(3) == sorted(folders[:2])
    updated = _files(per_round=True)  # with dataset updates round r trains only on its own targets
    assert updated.clip_views(2) == ["v00", "v01"] and updated.earlier_targets(2) == []


def test_a_round_folder_needs_no_round_plan():
    """The refine rule names its round's folder without the views checkpoint (a remote SLURM job
    cannot ask a checkpoint its rule does not list as input): the same folder the plan gives."""
    from anigs.animate.plan import RoundPlan
    from anigs.stages.round_files import RoundFiles, round_folder

    files = RoundFiles(RoundPlan(6), "results", "demo", "full", False)
    assert round_folder("results", "demo", "full", 2) == files.folder(2) == "results/demo/full/round2"
