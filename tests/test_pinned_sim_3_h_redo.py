"""`sim/frames.py`'s redo policy (`FrameRunner._advance`) on a stand-in simulator whose frame check answers
from a script: a frame whose particles left the active box is redone with more slack (s → 2s + 2), the second
escape on the whole grid (per-fragment boxes only grow their slack); a frame whose pool of multi-fragment nodes
overflowed is redone with a pool for twice the current capacity; slot overflows are reported, never redone;
after eight tries the frame stands. Every try starts from the saved state, and the frame ends exactly on its
time. The pool's expected rows follow the rows used, halving at most per try."""

import pytest
import torch

from fracture_gs.errors import SimulationDiverged
from fracture_gs.sim.boxes.storage import BoxStorage
from fracture_gs.sim.frames import FrameRunner
from fracture_gs.sim.grid.layout import pool_capacity
from fracture_gs.sim.grid.slots import SlotStorage


class _Grid:
    def __init__(self, log, capacity):
        self.log, self.capacity = log, capacity

    def ensure_pool(self, rows):
        self.log.append(("pool", rows))
        self.capacity = max(self.capacity, pool_capacity(rows))

    def zero(self):
        self.log.append("zero")


class _Slots:
    """The slot storage's pool and whole-grid rules (`SlotStorage`'s own methods) over a logged grid."""

    frame_done, grow_pool, whole_grid = SlotStorage.frame_done, SlotStorage.grow_pool, SlotStorage.whole_grid

    def __init__(self, sim, log, capacity, pool_rows):
        self.sim, self.log, self.grid, self.pool_rows = sim, log, _Grid(log, capacity), pool_rows

    def reset_box(self):
        self.log.append("reset_boxes")

    def set_solo(self, mask):
        self.log.append(("solo", mask))


class _Boxes:
    whole_grid = BoxStorage.whole_grid


class _Sim:
    """The attributes `FrameRunner._advance` reads of its simulator; `fit_active_box` logs the slack and pool."""

    def __init__(self, boxed, multifield, capacity, pool_rows):
        self.log = []
        self.boxed, self.multifield, self.device = boxed, multifield, "cpu"
        self.slots = _Slots(self, self.log, capacity, pool_rows)
        self.storage = _Boxes() if boxed else self.slots
        self.time, self.frame, self.substeps, self.dt = 1.0, 3, 30, None
        self.counts = torch.ones(4, dtype=torch.int32)
        self._diagnostics = None
        self.runner = None

    def fit_active_box(self, frame_dt):
        self.log.append(("fit", self.runner.box_slack, self.slots.pool_rows))
        if self.multifield and not self.boxed:
            self.slots.grid.ensure_pool(self.slots.pool_rows)
        return 0.5


class _Loop(FrameRunner):
    """A `FrameRunner` whose substeps and frame check answer from a script: `checks` = (bad, escaped, slot
    overflows, pool overflows, rows used), one per try."""

    def __init__(self, checks, boxed=False, multifield=True, capacity=256, pool_rows=100):
        self.host = _Sim(boxed, multifield, capacity, pool_rows)
        super().__init__(self.host)
        self.host.runner = self
        self.checks, self.log = list(checks), self.host.log

    # the simulator's state as the old tests read it
    time = property(lambda self: self.host.time)
    frame = property(lambda self: self.host.frame)
    substeps = property(lambda self: self.host.substeps)
    pool_rows = property(lambda self: self.host.slots.pool_rows)
    grid = property(lambda self: self.host.slots.grid)

    def frame_substeps(self, frame_dt, vmax=None):
        self.log.append(("substeps", vmax))
        return 3, frame_dt / 3

    def run_substeps(self, n, dt, start):
        h = self.host
        assert h.time == start and h.counts[1:].tolist() == [0, 0, 0]  # a try starts clean
        h.counts[1:] = 7  # the try's counters
        h.time += n * dt  # summed Δt (drifts)
        h.substeps += n

    def frame_check(self, dt):
        return self.checks.pop(0)

    def save_state(self):
        self.log.append("save")

    def restore_state(self):
        self.log.append("restore")

    def poll_provider(self):
        self.log.append("poll")

    def raise_diverged(self, dt, bad):
        raise SimulationDiverged(f"{bad} diverged", frame=self.host.frame, count=bad, cause="test")


def _fits(loop):
    return [e for e in loop.log if isinstance(e, tuple) and e[0] == "fit"]


def test_a_pool_overflow_redoes_the_frame_with_a_pool_twice_the_capacity():
    """Capacity 256, 300 rows used and an overflow: the second try fits the box with 512 expected rows
    (2 × 256, the pool then holds 1024 rows), no slack added; then no overflow: one redo, the state restored
    once, the frame ends at exactly start + frame_dt with 3 substeps counted once, and the provider polled once
    at the end."""
    loop = _Loop([(0, 0, 0, 5, 300), (0, 0, 0, 0, 300)], capacity=256)
    assert loop._advance(0.1) == 3
    assert [f[2] for f in _fits(loop)] == [100, 512]
    assert [f[1] for f in _fits(loop)] == [0, 0]
    assert loop.grid.capacity == 1024
    assert loop.frame_redos == 1 and loop.log.count("restore") == 1 and loop.log.count("save") == 1
    assert loop.pool_overflow == 0 and loop.slot_overflow == 0
    assert loop.pool_rows == 300  # max(rows used, 512 // 2)
    assert loop.time == 1.1 and loop.frame == 4 and loop.substeps == 33
    assert loop.log[-1] == "poll" and loop.log.count("poll") == 1


def test_expected_pool_rows_follow_the_rows_used_halving_at_most_per_frame():
    """No overflow: the expected rows become max(rows used, half the previous): 1000 → 500 with 100 used,
    → 250, then 400 used gives 400."""
    loop = _Loop([(0, 0, 0, 0, 100), (0, 0, 0, 0, 100), (0, 0, 0, 0, 400)], pool_rows=1000)
    seen = []
    for _ in range(3):
        loop._advance(0.1)
        seen.append(loop.pool_rows)
    assert seen == [500, 250, 400] and loop.frame_redos == 0


def test_escapes_grow_the_slack_then_take_the_whole_grid():
    """Escapes on three tries: slack 0 → 2 → 6 (2s + 2), the first two tries fit the active box, the third
    runs on the whole grid (pool sized first, boxes reset, grid zeroed, solo flags cleared, the CFL step
    taken without a known max |v|). The expected pool rows halve per try (100 → 50 → 25: 10 used)."""
    loop = _Loop([(0, 4, 0, 0, 10), (0, 1, 0, 0, 10), (0, 0, 0, 0, 10)])
    loop._advance(0.1)
    assert [f[1] for f in _fits(loop)] == [0, 2]
    assert loop.box_slack == 6 and loop.frame_redos == 2
    third = loop.log[len(loop.log) - 1 - loop.log[::-1].index("restore") + 1 :]  # after the last restore
    assert third[:5] == [("pool", 25), "reset_boxes", "zero", ("solo", None), ("substeps", None)]


def test_per_fragment_boxes_only_grow_their_slack():
    """With per-fragment boxes every try fits boxes (never the whole grid): slack 0, 2, 6, 14."""
    loop = _Loop([(0, 1, 0, 0, 0)] * 3 + [(0, 0, 0, 0, 0)], boxed=True)
    loop._advance(0.1)
    assert [f[1] for f in _fits(loop)] == [0, 2, 6, 14]
    assert "reset_boxes" not in loop.log and loop.frame_redos == 3


def test_slot_overflows_are_reported_not_redone_and_eight_tries_end_the_redos():
    """A slot overflow alone keeps the frame (reported and summed over frames). A pool that overflows on
    every try stops after 8 tries (7 redos) and the frame stands with its overflow reported."""
    loop = _Loop([(0, 0, 3, 0, 10), (0, 0, 4, 0, 10)])
    loop._advance(0.1)
    loop._advance(0.1)
    assert loop.frame_redos == 0 and loop.slot_overflow == 4 and loop.slot_overflow_total == 7
    loop = _Loop([(0, 0, 0, 2, 10)] * 8)
    loop._advance(0.1)
    assert len(_fits(loop)) == 8 and loop.frame_redos == 7 and loop.pool_overflow == 2
    assert loop.time == 1.1 and loop.frame == 4


def test_a_diverged_frame_raises_after_the_clock_moved_and_before_the_provider():
    """Diverged particles: the frame's time and count advance, then SimulationDiverged; the provider is not
    asked (no event latches on a diverged state)."""
    loop = _Loop([(5, 0, 0, 0, 10)])
    with pytest.raises(SimulationDiverged, match="5 diverged"):
        loop._advance(0.1)
    assert loop.frame == 4 and loop.time == 1.1 and "poll" not in loop.log
