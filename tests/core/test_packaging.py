"""The build metadata: ``project.license`` is an SPDX expression (the TOML-table form stops
building with setuptools after 2027-02-18), and every place that installs setuptools asks for a
version that reads it (77 or later)."""
from __future__ import annotations

import re
import sys
from pathlib import Path

from packaging.requirements import Requirement
from packaging.version import Version

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI (pip vendors it too)
    from pip._vendor import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
FIRST_SPDX_SETUPTOOLS = Version("77")


def _allows_older(spec: Requirement) -> bool:
    """Whether the requirement admits a setuptools release before the first that reads SPDX."""
    return spec.specifier.contains("76.9", prereleases=False) or not str(spec.specifier)


def test_license_is_an_spdx_string():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert isinstance(project["license"], str), f"project.license must be an SPDX string, got {project['license']!r}"
    assert project["license"] == "MIT"


def test_build_requires_a_setuptools_that_reads_spdx():
    requires = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]["requires"]
    setuptools = [Requirement(r) for r in requires if Requirement(r).name == "setuptools"]
    assert len(setuptools) == 1, f"build-system.requires names setuptools {len(setuptools)} times: {requires}"
    assert not _allows_older(setuptools[0]), f"{setuptools[0]} admits setuptools < {FIRST_SPDX_SETUPTOOLS}"


def test_setup_script_upgrades_to_a_setuptools_that_reads_spdx():
    text = (ROOT / "envs" / "setup.sh").read_text()
    specs = [Requirement(m) for m in re.findall(r'"(setuptools[<>=!~][^"]*)"', text)]
    assert specs, "envs/setup.sh installs setuptools without a quoted version bound"
    assert all(not _allows_older(s) for s in specs), [str(s) for s in specs]
