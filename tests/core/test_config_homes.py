"""Every config section has one home: its stage's ``Config`` is a class of an ``anigs.<pkg>.config``
module, named after the stage (``<Stage>Config``)."""
from __future__ import annotations

import pytest

from anigs.registry import STAGES

SECTIONS = [s for s in STAGES if s.section]

# Names kept for now: the effects package is being reworked on another branch; the capture section is
# the photo import's (anigs.synth.capture.CaptureConfig is the synthetic camera path).
OTHER_NAMES = {"effects": "Config", "capture": "PhotosConfig"}


def _camel(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_"))


@pytest.mark.parametrize("stage", SECTIONS, ids=[s.name for s in SECTIONS])
def test_the_section_class_lives_in_a_config_module(stage):
    cls = stage.config_class()
    pkg, _, leaf = cls.__module__.rpartition(".")
    assert leaf == "config" and pkg.startswith("anigs."), f"{stage.name}: {cls.__module__}.{cls.__name__}"
    assert cls.__name__ == OTHER_NAMES.get(stage.name, f"{_camel(stage.name)}Config")


def test_the_names_are_checked_for_every_section():
    assert len(SECTIONS) >= 14
    assert set(OTHER_NAMES) <= {s.name for s in SECTIONS}
