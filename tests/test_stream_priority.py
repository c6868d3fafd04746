"""`runtime.side_stream` gives the solver's streams CUDA's highest priority and every other stream the default
(lowest), so the renderer's and the composer's kernels queued beside a frame never go ahead of the solver's, whose
frame the next host read waits for (measured on an H200: BENCHMARKS.md, "The main job end to end"). A priority
orders only which ready blocks the device starts next, so no number depends on it.

On the CPU, torch's stream class is swapped for one that records what it was asked for; with `--device cuda` the
real streams are checked."""

import pytest
import torch

from fracture_gs import runtime

SOLVER = ("simulate", "record", "fork")  # the substeps, the diagnostics' graphs, the solver's forked launches
BESIDE = ("render", "compose", "main")  # the render worker, the comparison's composers, a variant thread's own


class _FakeStream:
    made: list = []

    def __init__(self, device=None, priority=0):
        self.device, self.priority = device, priority
        _FakeStream.made.append(self)


@pytest.fixture
def fresh_streams(monkeypatch):
    monkeypatch.setattr(runtime, "_side_streams", {})


def test_the_solver_streams_get_the_highest_priority_and_the_rest_the_default(fresh_streams, monkeypatch):
    monkeypatch.setattr(torch.cuda, "Stream", _FakeStream)
    _FakeStream.made = []
    assert runtime.side_stream("cuda:0").priority == runtime.HIGHEST_PRIORITY  # the default purpose: the solver's
    for purpose in SOLVER:
        assert runtime.side_stream("cuda:0", purpose).priority == runtime.HIGHEST_PRIORITY, purpose
    for purpose in BESIDE:
        assert runtime.side_stream("cuda:0", purpose).priority == 0, purpose
    # one stream per (device, purpose, lane), made once: "simulate" was asked for twice
    assert len(_FakeStream.made) == 1 + len(SOLVER) + len(BESIDE) - 1
    assert runtime.side_stream("cuda:0", "render") is runtime.side_stream("cuda:0", "render")
    with runtime.stream_lane(1):  # another lane's solver stream: a stream of its own, as high
        other = runtime.side_stream("cuda:0")
    assert other is not runtime.side_stream("cuda:0") and other.priority == runtime.HIGHEST_PRIORITY


def test_the_highest_priority_is_above_any_device_range():
    """CUDA devices have had at most 6 levels (0 … −5); torch maps a number past the range to its end."""
    assert runtime.HIGHEST_PRIORITY <= -6


def test_real_streams_take_the_device_s_highest_priority(device, fresh_streams):
    if not device.startswith("cuda"):
        # the CPU has no streams: the solver's launches run in order on the calling thread
        assert runtime.warp_stream(device) is None
        return
    solver, render = runtime.side_stream(device), runtime.side_stream(device, "render")
    best = torch.cuda.Stream(device, priority=runtime.HIGHEST_PRIORITY).priority
    assert solver.priority == best < render.priority == 0
