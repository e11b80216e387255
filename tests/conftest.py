"""Shared pytest options (``--device``, default cpu; the ``gpu`` and ``browser`` markers) and fixtures
(``one_thread``).

Shared scene builders live in ``tests/_scenes.py``."""
from __future__ import annotations

import os

# One BLAS thread for numpy, set before numpy loads (torch imports it): OpenBLAS's threads spin
# while they wait for each other and stall on an oversubscribed machine (tests/metrics/
# test_bootstrap.py's SVDs took 558 s instead of 16 s on a loaded 2-core machine). Torch's own
# threads: the one_thread fixture. Export OPENBLAS_NUM_THREADS to choose another count.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402
import torch  # noqa: E402


def pytest_addoption(parser):
    parser.addoption("--device", default="cpu", help="device for tests that take one (cpu, cuda, auto)")


@pytest.hookimpl(tryfirst=True)  # before `-m "not slow"` deselects: a browser test belongs to the full tier
def pytest_collection_modifyitems(config, items):
    if not torch.cuda.is_available():
        skip = pytest.mark.skip(reason="needs a CUDA device (none on this machine)")
        for item in items:
            if item.get_closest_marker("gpu") is not None:  # the marker, not any keyword (file names count there)
                item.add_marker(skip)
    browser = [item for item in items if item.get_closest_marker("browser") is not None]
    if browser:
        from tests._browser import MISSING, REQUIRED, SKIP_REASON

        for item in browser:
            item.add_marker(pytest.mark.slow)
            if MISSING and not REQUIRED:
                item.add_marker(pytest.mark.skip(reason=SKIP_REASON))


@pytest.fixture
def device(request) -> torch.device:
    from anigs.device import get_device

    return get_device(request.config.getoption("--device"))


@pytest.fixture
def one_thread():
    """One torch/OpenMP thread for the test: the CPU kernel's threads stall on an oversubscribed
    machine (use with ``pytestmark = pytest.mark.usefixtures("one_thread")``)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)
