"""`runtime.StreamFork`: launches inside `with fork:` start only after everything issued before the fork, and
the join makes later launches wait for them, eagerly and as the parallel paths of a recorded CUDA graph. The
kernels before the fork and beside it spin, so on a GPU a missing edge shows as a wrong sum. On the CPU the
fork is a no-op and the same launches run in order."""

import contextlib

import pytest
import torch
import warp as wp

from fracture_gs.runtime import StreamFork, ensure_warp, side_stream, warp_stream

SPINS = 20000


@wp.kernel
def slow_fill(a: wp.array(dtype=float), value: float, spins: int):
    i = wp.tid()
    acc = float(0.0)  # noqa: UP018 (a dynamic Warp variable)
    for k in range(spins):
        acc = acc + wp.sin(float(k + i))
    a[i] = value + wp.where(acc > 1.0e30, acc, 0.0)  # the loop's result is used, so it is not removed


@wp.kernel
def plus_one(a: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = a[i] + 1.0


@wp.kernel
def add(a: wp.array(dtype=float), b: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = a[i] + b[i]


def _arrays(device, n=4096):
    ensure_warp()
    tensors = [torch.zeros(n, device=device) for _ in range(4)]
    return tensors, [wp.from_torch(t) for t in tensors]


def _launch(device, kernel, inputs, n=4096):
    wp.launch(kernel, dim=n, inputs=inputs, device=device, stream=warp_stream(device))


def _check_eagerly_and_recorded(device, launches, tensors, streams):
    """`launches()` ends with d = b + c = 4 everywhere, run eagerly and (CUDA) recorded once and replayed, where
    the fork's launches went to a stream of their own."""
    scope = torch.cuda.stream(side_stream(device)) if device.startswith("cuda") else contextlib.nullcontext()
    with scope:  # graphs record a non-default stream
        launches()
        assert (tensors[3].cpu() == 4.0).all()
        if device.startswith("cuda"):
            assert streams["fork"] is not streams["main"], "the launches inside went to the fork's own stream"
            wp.load_module(device=device)
            with wp.ScopedCapture(device=device, stream=warp_stream(device), force_module_load=False) as capture:
                launches()
            for _ in range(3):
                for t in tensors:
                    t.zero_()
                wp.capture_launch(capture.graph, stream=warp_stream(device))
                assert (tensors[3].cpu() == 4.0).all(), "the recorded graph keeps both edges"


@pytest.mark.slow
def test_a_fork_waits_for_what_came_before_and_the_join_for_the_fork(device):
    tensors, (a, b, c, d) = _arrays(device)
    fork = StreamFork(device)
    streams = {}

    def launches():
        _launch(device, slow_fill, [a, 1.0, SPINS])
        with fork:
            streams["fork"] = warp_stream(device)
            _launch(device, plus_one, [a, b])  # needs a: the fork's edge
        streams["main"] = warp_stream(device)
        _launch(device, slow_fill, [c, 2.0, SPINS])  # beside it
        fork.join()
        _launch(device, add, [b, c, d])  # needs b: the join's edge

    _check_eagerly_and_recorded(device, launches, tensors, streams)


@pytest.mark.slow
def test_a_fork_opened_early_waits_only_for_what_came_before_it(device):
    """`fork.open()` marks the fork point; a launch issued on the current stream after it and a launch inside the
    fork issued later still start from that point (the simulator issues G2P first and the next P2G's clear beside
    it): the fork sees what came before the mark, the join makes later launches wait for both."""
    tensors, (a, b, c, d) = _arrays(device)
    fork = StreamFork(device)
    streams = {}

    def launches():
        _launch(device, slow_fill, [a, 1.0, SPINS])
        fork.open()
        streams["main"] = warp_stream(device)
        _launch(device, slow_fill, [c, 2.0, SPINS])  # issued first, on the current stream
        with fork:
            streams["fork"] = warp_stream(device)
            _launch(device, plus_one, [a, b])  # needs a, from before the mark
        fork.join()
        _launch(device, add, [b, c, d])  # needs b and c

    _check_eagerly_and_recorded(device, launches, tensors, streams)
    assert fork.forks == (2 if device.startswith("cuda") else 0), "one fork eagerly, one recorded"
