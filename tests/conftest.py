"""Shared pytest options: ``--device`` (default cpu) and the ``gpu`` marker."""
from __future__ import annotations

import pytest
import torch


def pytest_addoption(parser):
    parser.addoption("--device", default="cpu", help="device for tests that take one (cpu, cuda, auto)")


def pytest_collection_modifyitems(config, items):
    if not torch.cuda.is_available():
        skip = pytest.mark.skip(reason="needs a CUDA device (none on this machine)")
        for item in items:
            if "gpu" in item.keywords:
                item.add_marker(skip)


@pytest.fixture
def device(request) -> torch.device:
    from anigs.device import get_device

    return get_device(request.config.getoption("--device"))
