"""Every config section has one home: its stage's ``Config`` is a class of an ``anigs.<pkg>.config``
module, named after the stage (``<Stage>Config``), and one mechanism: every section and nested section is a
:class:`anigs.typed_config.Section` that checks its values in ``validate`` alone."""
from __future__ import annotations

import dataclasses

import pytest

from anigs.registry import STAGES
from anigs.typed_config import Section, nested_sections

SECTIONS = [s for s in STAGES if s.section]

def _camel(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_"))


@pytest.mark.parametrize("stage", SECTIONS, ids=[s.name for s in SECTIONS])
def test_the_section_class_lives_in_a_config_module(stage):
    cls = stage.config_class()
    pkg, _, leaf = cls.__module__.rpartition(".")
    assert leaf == "config" and pkg.startswith("anigs."), f"{stage.name}: {cls.__module__}.{cls.__name__}"
    assert cls.__name__ == f"{_camel(stage.name)}Config"


def test_the_names_are_checked_for_every_section():
    assert len(SECTIONS) >= 14


def _all_sections(cls: type, path: str) -> list[tuple[str, type]]:
    out = [(path, cls)]
    for key, sub in nested_sections(cls).items():
        out += _all_sections(sub, f"{path}.{key}")
    return out


NESTED = [pair for s in SECTIONS for pair in _all_sections(s.config_class(), s.name)]


@pytest.mark.parametrize("path,cls", NESTED, ids=[p for p, _ in NESTED])
def test_every_section_is_built_one_way(path, cls):
    assert dataclasses.is_dataclass(cls) and issubclass(cls, Section), f"{path}: {cls.__qualname__} is no Section"
    own = [name for name in ("from_dict", "__post_init__") if name in vars(cls)]
    assert not own, f"{path}: {cls.__qualname__} defines {own}: checks belong in validate()"


def test_construction_validates():
    cls = next(c for p, c in NESTED if p == "views")
    with pytest.raises(ValueError, match="num_locations"):
        cls(num_locations=0)
