"""`sim/clock.py`'s host side (`FrameClock.set`): a frame's table of substep times and timed-region rows is
written into buffers that grow only when a frame has more substeps than fit, and then to at least twice their
size (so a frame that is a little longer than the last does not move the buffers, which would make every
recorded substep graph record again); the times are the host's values rounded to float32 and the running
substep is rewound to 0."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock

ensure_warp()


def _table(n, regions):
    times = [0.1 + i / 3.0 for i in range(n)]  # not binary-exact: the float32 rounding shows
    on = [(i + r) % 2 for i in range(n) for r in range(regions)]
    value = [[float(i), float(r), -1.0] for i in range(n) for r in range(regions)]
    return times, on, value


def test_buffers_double_when_a_frame_outgrows_them_and_stay_for_shorter_frames():
    """Capacity starts at 64 substeps: a frame of 64 fits (nothing moves), 65 grows it to 128 (twice, not
    65), then 100 and 128 fit; 300 (more than twice 128) grows it to exactly 300. `set` says whether the
    buffers moved, and the Warp view then wraps the new tensors."""
    c = FrameClock("cpu", regions=2)
    assert c.capacity == 64
    steps = [(64, False, 64), (65, True, 128), (100, False, 128), (128, False, 128), (300, True, 300)]
    for n, moved, cap in steps:
        before = c.times.data_ptr()
        times, on, value = _table(n, 2)
        assert c.set(1e-3, times, on, value) is moved, n
        assert c.capacity == cap and c.times.numel() == cap, n
        assert (c.times.data_ptr() != before) is moved, n
        assert c.on.numel() == 2 * cap and tuple(c.value.shape) == (2 * cap, 3), n
        assert wp.to_torch(c.view.times).data_ptr() == c.times.data_ptr()
        assert wp.to_torch(c.view.region_on).data_ptr() == c.on.data_ptr()
        assert wp.to_torch(c.view.region_value).data_ptr() == c.value.data_ptr()


def test_a_frames_table_is_its_times_in_float32_with_the_substep_rewound():
    """After `set`: Δt in its one-entry tensor, the first n times equal to the host's doubles rounded to
    float32, the timed-region rows in substep-major order (substep i, region r at i·R + r), and the running
    substep back at 0 (a frame always starts at its first substep)."""
    c = FrameClock("cpu", regions=3)
    times, on, value = _table(10, 3)
    c.step.fill_(7)  # where the previous frame ended
    c.set(2.5e-4, times, on, value)
    assert int(c.step) == 0
    assert c.dt.tolist() == torch.tensor([2.5e-4], dtype=torch.float32).tolist()
    assert c.times[:10].tolist() == torch.tensor(times, dtype=torch.float32).tolist()
    assert c.times[:10].tolist() != times  # the rounding is real (1/3 is not a float32)
    assert c.on[:30].tolist() == on
    assert c.value[:30].tolist() == value
    assert c.value[4].tolist() == [1.0, 1.0, -1.0]  # substep 1, region 1


def test_a_clock_without_regions_ignores_region_tables():
    """With no timed regions (R = 0) only the times are written; the region buffers keep one spare entry
    (Warp needs a non-empty array) and are not touched."""
    c = FrameClock("cpu", regions=0)
    assert c.on.numel() == 1 and tuple(c.value.shape) == (1, 3)
    times, _, _ = _table(5, 0)
    assert c.set(1e-3, times, [1] * 5, [[9.0, 9.0, 9.0]] * 5) is False
    assert c.on.tolist() == [0] and c.value.tolist() == [[0.0, 0.0, 0.0]]
    assert c.times[:5].tolist() == torch.tensor(times, dtype=torch.float32).tolist()
