"""The frame's clock on the device: Δt, the time of every substep, and which substep is running.

Kernels read Δt and t from these arrays instead of taking them as launch arguments, so one
recorded substep (a CUDA graph) replays every substep of every frame: the host writes the frame's
table once (t_i = the host's double-precision time of substep i, rounded to float32 exactly as a
launch argument would be; the timed particle regions' activity and velocity change per substep),
and the recorded `tick` advances the substep index. Bitwise the same as passing the values as
arguments.
"""

from __future__ import annotations

import torch
import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.struct
class Clock:
    """Time on the device (`FrameClock.view`)."""

    dt: wp.array(dtype=float)  # [1] substep Δt [s]
    times: wp.array(dtype=float)  # [n] time at the start of substep i of the frame [s]
    step: wp.array(dtype=wp.int32)  # [1] index of the running substep
    region_on: wp.array(dtype=wp.int32)  # [n · R] timed region r active in substep i
    region_value: wp.array(dtype=wp.vec3)  # [n · R] its velocity change (impulse) or velocity (override)
    regions: int  # R


@wp.func
def clock_dt(c: Clock):
    return c.dt[0]


@wp.func
def clock_time(c: Clock):
    return c.times[c.step[0]]


@wp.kernel
def tick(c: Clock):
    """Next substep (recorded last in every substep)."""
    c.step[0] = c.step[0] + 1


class FrameClock:
    """Host side: the clock's tensors, grown when a frame has more substeps than fit."""

    def __init__(self, device: str, regions: int):
        self.device = device
        self.regions = regions
        self.capacity = 0
        self.dt = torch.zeros(1, dtype=torch.float32, device=device)
        self.step = torch.zeros(1, dtype=torch.int32, device=device)
        self._grow(64)

    def _grow(self, n: int) -> None:
        self.capacity = n
        self.times = torch.zeros(n, dtype=torch.float32, device=self.device)
        self.on = torch.zeros(max(1, n * self.regions), dtype=torch.int32, device=self.device)
        self.value = torch.zeros((max(1, n * self.regions), 3), dtype=torch.float32, device=self.device)
        v = Clock()
        v.dt = wp.from_torch(self.dt)
        v.times = wp.from_torch(self.times)
        v.step = wp.from_torch(self.step)
        v.region_on = wp.from_torch(self.on)
        v.region_value = wp.from_torch(self.value, dtype=wp.vec3)
        v.regions = self.regions
        self.view = v

    def set(self, dt: float, times: list, on=None, value=None) -> bool:
        """Write a frame's table (host → device, no sync) and rewind to substep 0; returns whether the
        buffers moved (a recorded graph must then be recorded again)."""
        n = len(times)
        moved = n > self.capacity
        if moved:
            self._grow(max(n, 2 * self.capacity))
        self.dt.fill_(dt)
        self.step.zero_()
        self.times[:n].copy_(torch.tensor(times, dtype=torch.float32), non_blocking=True)
        if self.regions and on is not None:
            self.on[: n * self.regions].copy_(torch.tensor(on, dtype=torch.int32).reshape(-1), non_blocking=True)
            self.value[: n * self.regions].copy_(
                torch.tensor(value, dtype=torch.float32).reshape(-1, 3), non_blocking=True
            )
        return moved
