"""The stage contract base: layout paths and folders, checked loaders, flags derived from Inputs fields."""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from anigs.contract import File, Inputs, Outputs, check_array, outputs_of
from anigs.stages.targets import stage_outputs


class _Out(Outputs):
    STAGE = "toy"
    FOLDER = "{scene}/{variant}/toy"
    LAYOUT = {
        "report": File("report.json", "the report"),
        "dynamic": File("dynamic.npy", "bool [N]"),
        "mask": File("{view}.png", "uint8 [H, W]"),
    }


@dataclass
class _In(Inputs):
    toy: _Out
    canonical: Path = field(metadata={"help": "canonical PLY"})
    masks_dir: Path | None = None
    effects: _Out | None = None
    steps: int = 3
    names: list[str] | None = None
    keep_work: bool = False


def test_files_under_the_results_root_keep_the_fields_not_given():
    assert _Out.under("res") == "res/{scene}/{variant}/toy"
    assert _Out.under("res", "mask", scene="demo") == "res/demo/{variant}/toy/{view}.png"
    assert _Out.under("res", "report", scene="demo", variant="full") == "res/demo/full/toy/report.json"
    assert stage_outputs("masks").under("r", "dynamic", scene="s") == "r/s/masks/dynamic.npy"
    assert stage_outputs("anigs.study.layout").under("r") == "r/study"
    with pytest.raises(KeyError):
        _Out.under("res", "nope")


def test_paths_and_patterns(tmp_path):
    o = _Out(tmp_path)
    assert o.path("mask", view="v03") == tmp_path / "v03.png"
    assert _Out.pattern("mask", "results/{scene}/toy") == "results/{scene}/toy/{view}.png"
    with pytest.raises(KeyError, match="needs \\['view'\\]"):
        o.path("mask")
    with pytest.raises(KeyError, match="has no file 'nope'"):
        o.path("nope")


def test_folder_under_the_results_root(tmp_path):
    o = _Out.at(tmp_path, scene="demo", variant="full")
    assert o == _Out(tmp_path / "demo" / "full" / "toy")
    assert o.path("report") == tmp_path / "demo/full/toy/report.json"
    with pytest.raises(KeyError, match="variant"):
        _Out.at(tmp_path, scene="demo")
    with pytest.raises(ValueError, match="has no FOLDER"):
        type("NoFolder", (Outputs,), {}).at(tmp_path)


def test_outputs_of_a_stage_module():
    import types

    one = types.ModuleType("one")
    one.Outputs = _Out
    assert outputs_of(one) == (_Out,)
    two = types.ModuleType("two")
    two.Outputs, two.OUTPUTS = _Out, [Outputs, _Out]
    assert outputs_of(two) == (Outputs, _Out)
    assert outputs_of(types.ModuleType("none")) == ()


def test_checked_loaders_name_the_file(tmp_path):
    o = _Out(tmp_path)
    with pytest.raises(FileNotFoundError, match="run the toy stage"):
        o.array("dynamic")
    np.save(tmp_path / "dynamic.npy", np.zeros(5, np.float32))
    with pytest.raises(ValueError, match="dynamic.npy: dtype float32"):
        o.array("dynamic", "b", (5,))
    np.save(tmp_path / "dynamic.npy", np.zeros(5, bool))
    assert o.array("dynamic", "b", (5,)).shape == (5,)
    with pytest.raises(ValueError, match=r"shape \[5\] where \[4\]"):
        o.array("dynamic", "b", (4,))
    (tmp_path / "report.json").write_text("{not json")
    with pytest.raises(ValueError, match="report.json: not valid JSON"):
        o.json("report")
    assert check_array(np.zeros((2, 3)), "x", "f", (None, 3)).shape == (2, 3)


def test_flags_derive_from_fields_and_round_trip(tmp_path):
    p = argparse.ArgumentParser()
    _In.add_arguments(p)
    flags = {a.option_strings[0] for a in p._actions if a.option_strings}
    assert {"--toy", "--canonical", "--masks-dir", "--effects", "--steps", "--names", "--keep-work"} <= flags
    with pytest.raises(SystemExit):
        p.parse_args(["--canonical", "c.ply"])          # --toy is required
    args = p.parse_args(["--toy", str(tmp_path), "--canonical", "c.ply", "--steps", "7", "--names", "a", "b"])
    inp = _In.from_args(args)
    assert inp.toy == _Out(tmp_path) and inp.canonical == Path("c.ply") and inp.steps == 7
    assert inp.effects is None and inp.names == ["a", "b"] and inp.keep_work is False
    again = _In.from_args(p.parse_args(inp.argv()))
    assert again == inp


def test_stage_command_gives_back_the_inputs_through_the_stage_s_own_flags(tmp_path):
    """The workflow's one command builder (params.cmd of every stage rule): argv from the stage's
    Inputs, parsed back by the stage's own command line into equal Inputs (quoting included)."""
    import shlex

    from anigs.stages import masks
    from anigs.stages.command import stage_arguments, stage_command

    cmd = stage_command("masks", '{"backend": "labels"}', canonical=tmp_path / "a b.ply", views=tmp_path / "views",
                        out=tmp_path / "masks", effects=tmp_path / "effects")
    argv = shlex.split(cmd)
    assert argv[0] == "masks" and argv[-2:] == ["--params", '{"backend": "labels"}']
    p = argparse.ArgumentParser()
    stage_arguments(masks, "masks", p)
    back = masks.Inputs.from_args(p.parse_args(argv[1:]))
    assert back.canonical == tmp_path / "a b.ply" and back.views == masks.ViewsOutputs(tmp_path / "views")
    assert back.effects.root == tmp_path / "effects" and back.labels is None
