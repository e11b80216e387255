"""Fixtures shared by the views tests."""
from __future__ import annotations

import pytest

from tests.masks.test_lift import toy_scene


@pytest.fixture(scope="module")
def scene():
    """The toy scene on a ring of 8 cameras: (Gaussians, labels int [N], cameras)."""
    return toy_scene(ring=8)
