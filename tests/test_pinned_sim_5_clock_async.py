"""`FrameClock.set` writes a frame's table host → device without a sync ("no sync", sim/clock.py).

The frame loop calls `set` before every frame's recorded substeps; on a GPU a blocking copy would make the host
wait for the stream each frame (the launches queued behind it could no longer overlap the host's next frame).
Every copy of the table (the substep times, the timed regions' on/off flags and values) is therefore issued with
`non_blocking=True`; Δt and the substep counter are set by device-side fills. The copies are observed through a
torch function mode, so the test runs on the CPU, where a blocking and a non-blocking copy give the same values.
"""

from __future__ import annotations

import torch
from torch.overrides import TorchFunctionMode

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock

ensure_warp()


class _Copies(TorchFunctionMode):
    """Records every `Tensor.copy_` (destination size, non_blocking) issued inside the mode."""

    def __init__(self):
        super().__init__()
        self.copies: list[tuple[int, bool]] = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if func is torch.Tensor.copy_:
            non_blocking = kwargs.get("non_blocking", args[2] if len(args) > 2 else False)
            self.copies.append((args[0].numel(), bool(non_blocking)))
        return func(*args, **kwargs)


def test_a_frames_table_is_written_with_non_blocking_copies_only():
    """A frame of 5 substeps with 2 timed regions: three copies (5 times, 10 on/off flags, 10 × 3 values), each
    non-blocking; the table lands as written."""
    c = FrameClock("cpu", regions=2)
    times = [0.1 * i for i in range(5)]
    on = [[1, 0]] * 5
    value = [[[1.0, 2.0, 3.0], [0.0, 0.0, -1.0]]] * 5
    with _Copies() as spy:
        c.set(1e-3, times, on, value)
    assert sorted(spy.copies) == [(5, True), (10, True), (30, True)]
    assert c.on[:10].tolist() == [1, 0] * 5
    assert c.value[:2].tolist() == [[1.0, 2.0, 3.0], [0.0, 0.0, -1.0]]


def test_a_clock_without_regions_copies_only_its_times_non_blocking():
    """No timed regions: one non-blocking copy (the times), whatever region tables the caller passes."""
    c = FrameClock("cpu", regions=0)
    with _Copies() as spy:
        c.set(1e-3, [0.0, 0.001], [1, 1], [[1.0, 1.0, 1.0]] * 2)
    assert spy.copies == [(2, True)]
