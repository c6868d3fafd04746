"""Shared fixtures: `--device cpu|cuda` selects where solver tests run (CUDA skips without a GPU)."""

import os

import numpy as np
import pytest
import torch


def pytest_addoption(parser):
    parser.addoption("--device", default="cpu", help="device for solver tests: cpu or cuda[:N]")


@pytest.fixture(scope="session")
def device(request):
    dev = request.config.getoption("--device")
    if dev.startswith("cuda") and not torch.cuda.is_available():
        pytest.skip("CUDA device requested but not available")
    return "cuda:0" if dev == "cuda" else dev


@pytest.fixture
def seed():
    """A fresh seed per test run (printed on failure through the test id in assertion messages)."""
    s = int(os.environ.get("FGS_SEED", np.random.SeedSequence().entropy % (2**31)))
    torch.manual_seed(s)
    np.random.seed(s)
    return s


@pytest.fixture(scope="module")
def one_thread():
    """One intra-op torch thread: many tiny tensor ops are far slower with contended threads."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
