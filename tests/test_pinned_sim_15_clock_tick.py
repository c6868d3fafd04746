"""The frame clock (`sim.clock`): the recorded `tick` advances the substep index by exactly one per launch, from
the 0 that `FrameClock.set` rewinds it to; `set` writes Δt and the frame's substep times (float32), and the timed
regions' on/off flags and values row by row (substep i, region r at i·R + r); it reports that its buffers moved
exactly when a frame has more substeps than fit, and then at least doubles them (a recorded graph must be
recorded again only then)."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock, tick

ensure_warp()


def test_tick_counts_substeps_from_the_rewound_zero():
    """Three ticks after `set` read step 3; a new `set` rewinds to 0 and one tick reads 1."""
    c = FrameClock("cpu", 0)
    c.set(1e-3, [0.0, 1e-3, 2e-3, 3e-3])
    for want in (1, 2, 3):
        wp.launch(tick, dim=1, inputs=[c.view], device="cpu")
        assert c.step.tolist() == [want]
    c.set(1e-3, [0.0])
    assert c.step.tolist() == [0]
    wp.launch(tick, dim=1, inputs=[c.view], device="cpu")
    assert c.step.tolist() == [1]


def test_set_writes_the_table_and_grows_only_past_its_capacity():
    """Capacity 64 at start: a 3-substep frame fits (not moved) and writes Δt = 2⁻¹⁰ and the times as float32;
    64 substeps still fit; 65 move the buffers to 128 (twice 64), 300 to 300 (more than twice 128 asked); the
    view follows the new buffers (a tick after growing advances the new counter)."""
    c = FrameClock("cpu", 0)
    assert c.capacity == 64
    assert c.set(2.0**-10, [0.0, 0.1, 0.2]) is False
    assert c.dt.tolist() == [2.0**-10]
    assert torch.equal(c.times[:3], torch.tensor([0.0, 0.1, 0.2], dtype=torch.float32))
    assert c.set(1e-3, [0.0] * 64) is False and c.capacity == 64
    assert c.set(1e-3, [0.0] * 65) is True and c.capacity == 128
    assert c.set(1e-3, [0.0] * 300) is True and c.capacity == 300
    wp.launch(tick, dim=1, inputs=[c.view], device="cpu")
    assert c.step.tolist() == [1] and c.view.times.shape == (300,)


def test_region_tables_are_laid_out_substep_by_region():
    """Two regions over three substeps: flags [[1, 0], [1, 1], [0, 1]] and velocities per (substep, region) land at
    entry i·2 + r; without regions the tables stay one unused entry."""
    c = FrameClock("cpu", 2)
    on = [[1, 0], [1, 1], [0, 1]]
    value = [[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]], [[3.0, 0.0, 0.0], [0.0, 4.0, 0.0]], [[5.0, 0.0, 0.0], [0.0, 6.0, 0.0]]]
    c.set(1e-3, [0.0, 1e-3, 2e-3], on, value)
    assert c.on[:6].tolist() == [1, 0, 1, 1, 0, 1]
    assert c.value[:6, 0].tolist() == [1.0, 0.0, 3.0, 0.0, 5.0, 0.0]
    assert c.value[:6, 1].tolist() == [0.0, 2.0, 0.0, 4.0, 0.0, 6.0]
    assert c.view.regions == 2
    none = FrameClock("cpu", 0)
    none.set(1e-3, [0.0, 1e-3], [[]] * 2, [[]] * 2)
    assert none.on.shape == (1,) and none.value.shape == (1, 3) and none.view.regions == 0
