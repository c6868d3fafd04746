"""A frame of the solver: a whole number of substeps ending exactly on the frame time, recorded once
as a CUDA graph and replayed (or launched on the CPU), then one host read — divergence, particles
that left the active box, slot and pool overflows — that may roll the frame back and redo it, and
the fracture event provider, which may latch again (repeated fracture).

`FrameLoop` is the frame half of `Simulator` (a mixin: it uses the simulator's particles, grid,
clock and substep launches)."""

from __future__ import annotations

import math
from typing import Optional

import torch
import warp as wp

from ..errors import SimulationDiverged
from ..profiling import phases
from ..runtime import capture_lock, launch, side_stream, warp_stream
from .clock import tick
from .particles import SimulationError
from .storage import COUNT_ESCAPED, COUNT_POOL_OVERFLOW, COUNT_SLOT_OVERFLOW


class FrameLoop:
    """Frames of substeps with checks and redo (mixed into `Simulator`)."""

    def _set_clock(self, dt: float, times: list) -> list:
        """Write a frame's clock table (Δt, substep times, region activity); returns the activity flags."""
        on, value = self.boundaries.region_table(times, dt)
        if self.clock.set(dt, times, on, value):
            self._graph = None
        return on

    def _substep_launches(self, on: Optional[list], step: int = 0) -> None:
        """Every launch of one substep, the clock's tick last. `on`: the frame's region flags (only the
        regions active in substep `step` are launched), or None to launch them all (graph capture:
        each checks the clock's table itself)."""
        R = len(self.boundaries.regions)
        active = None if on is None else on[step * R : (step + 1) * R]
        self.boundaries.apply_regions(
            self.wp["x"], self.wp["v"], len(self.particles), self.clock.view, self.device, active
        )
        self.compute_stress(self.stress, commit=True)
        self.transfer()
        launch(tick, 1, [self.clock.view], self.device)

    def _graph_key(self) -> tuple:
        """Everything a recorded substep bakes in besides the clock: a change means recording again."""
        g = self.grid
        return (
            self.box,
            g.capacity,
            id(g.view),
            self.multifield,
            self.latched,
            self.n_fragments,
            self.normal_mode,
            self.topology.release_events if self.topology else 0,
            self.record_contact,
            self.cfg.wall_cells,
            self.clock.capacity,
            self._fan_cap,
            self._run_length(int(self.multifield)),
            self.concurrent,
            self.boxes.layout_key if self.boxed else None,
        )

    def _frame_substeps_run(self, n: int, dt: float, start: float) -> None:
        """The frame's n substeps: on CUDA one recorded substep (a CUDA graph on the simulator's own
        stream) replayed n times, recorded again when something it bakes in changed; else launches."""
        times, t = [], start
        for _ in range(n):
            times.append(t)
            t += dt
        on = self._set_clock(dt, times)
        self.grid.reset_claims()  # claims last one frame
        graphs = self.use_graphs and self.device.startswith("cuda") and self.frame > 0
        if graphs and (self._graph is None or self._graph_key() != self._graph_key_value):
            with self._stream_scope(), capture_lock, phases.capturing():
                with wp.ScopedCapture(
                    device=self.device, stream=warp_stream(self.device), force_module_load=False
                ) as capture:
                    self._substep_launches(None)
            self._graph, self._graph_key_value = capture.graph, self._graph_key()
        with self._stream_scope():
            for i in range(n):
                if graphs:
                    wp.capture_launch(self._graph, stream=warp_stream(self.device))
                else:
                    self._substep_launches(on, i)
        for _ in range(n):
            self.time += dt
            self.substeps += 1

    def frame_substeps(self, frame_dt: float, vmax: Optional[float] = None) -> tuple[int, float]:
        """(n, Δt) with n·Δt = frame_dt exactly and Δt ≤ cfg.dt (and the CFL bound if adaptive;
        `vmax`, the largest particle speed, is read from the device when not given)."""
        dt = self.cfg.dt
        if self.cfg.adaptive_dt:
            if vmax is None:
                vmax = float(self.particles.v.norm(dim=1).max())
            if math.isfinite(vmax):
                dt = min(dt, self.cfl_dt(vmax))
        n = max(1, math.ceil(frame_dt / dt - 1e-9))
        if n > self.cfg.max_substeps_per_frame:
            raise SimulationError(
                f"a frame of {frame_dt}s needs {n} substeps of {dt:.3g}s, over sim.max_substeps_per_frame"
            )
        return n, frame_dt / n

    MAX_TRIES = 8

    def advance(self, frame_dt: float) -> int:
        """Simulate one frame: n substeps, then the divergence check and the event provider.

        The frame runs on an active box (or per-fragment boxes) fitted at its start. If a particle's
        stencil left its box (P2G counts it) or the pool of multi-fragment nodes filled up, the frame is
        rolled back and redone: with more box slack (the second escape runs on the whole grid, where
        nothing can escape; per-fragment boxes only grow their slack) or with a pool twice as large. One
        host read per try for the active box and one for the frame's check (per-fragment boxes add the fit's
        two). On CUDA the frame runs on the simulator's own stream (graphs are recorded on a
        non-default stream), ordered after the caller's current stream and before it again at the end."""
        if not self.device.startswith("cuda"):
            return self._advance(frame_dt)
        if self._cuda_stream is None:
            self._cuda_stream = side_stream(self.device)
        caller = torch.cuda.current_stream(self.device)
        self._cuda_stream.wait_stream(caller)
        with torch.cuda.stream(self._cuda_stream):
            n = self._advance(frame_dt)
        caller.wait_stream(self._cuda_stream)
        return n

    def _advance(self, frame_dt: float) -> int:
        if self.substeps == 0:
            self._poll_provider()  # an oracle may latch before the first substep
        start, substeps0 = self.time, self.substeps
        self._save_state()
        escapes = 0
        for attempt in range(self.MAX_TRIES):
            if escapes < 2 or self.boxed:  # boxes grow with the slack instead of taking the whole grid
                vmax = self.fit_active_box(frame_dt)  # the frame's one host read also gives max |v|
            else:
                if self.multifield:
                    self.grid.ensure_pool(self.pool_rows)
                self._reset_boxes()
                self.grid.zero()
                self.set_solo(None)  # the whole grid, every particle claims its slots
                vmax = None
            n, dt = self.frame_substeps(frame_dt, vmax)
            self.dt = dt
            self.counts[COUNT_ESCAPED:] = 0
            self._frame_substeps_run(n, dt, start)
            bad, escaped, slot_overflow, pool_overflow, rows = self._frame_check(dt)
            self.pool_rows = max(rows, self.pool_rows // 2)
            if (escaped == 0 and pool_overflow == 0) or attempt == self.MAX_TRIES - 1:
                break
            self._restore_state()
            self.time, self.substeps = start, substeps0
            if escaped:
                escapes += 1
                self.box_slack = 2 * self.box_slack + 2
            if pool_overflow:
                self.pool_rows = 2 * self.grid.capacity
            self.frame_redos += 1
        self.slot_overflow, self.pool_overflow = slot_overflow, pool_overflow
        self.slot_overflow_total += slot_overflow
        self.time = start + frame_dt  # end exactly on the frame time (no drift from summing Δt)
        self.frame += 1
        if bad:
            self._raise_diverged(dt, bad)
        self._poll_provider()
        if self._diagnostics is not None:
            self._diagnostics.on_frame()
        return n

    def _save_state(self) -> None:
        """Copy what a frame can change into buffers made once (device copies, no sync)."""
        P, g = self.particles, self.grid
        keep = {"stats": g.contact_stats, "pair_stats": g.pair_stats, "counts": self.counts}
        if self._saved is None:
            self._saved = {k: torch.empty_like(getattr(P, k)) for k in self.MUTABLE}
            self._saved.update({k: torch.empty_like(t) for k, t in keep.items()})
        for k in self.MUTABLE:
            self._saved[k].copy_(getattr(P, k))
        for k, t in keep.items():
            self._saved[k].copy_(t)

    def _restore_state(self) -> None:
        P, g = self.particles, self.grid
        for k in self.MUTABLE:
            getattr(P, k).copy_(self._saved[k])
        g.contact_stats.copy_(self._saved["stats"])
        g.pair_stats.copy_(self._saved["pair_stats"])
        self.counts.copy_(self._saved["counts"])

    def _poll_provider(self) -> None:
        """Ask the event provider for a new topology (it returns one per fracture event) and latch it."""
        if self.provider is not None:
            topology = self.provider(self)
            if topology is not None:
                self.latch(topology)

    def _bad_particles(self, dt: float) -> torch.Tensor:
        """Particles with a non-finite x, v, F or C, or faster than Δx/Δt (a device count).

        F and C are checked too: the last substep of a frame can overflow F while x and v are still
        finite, and the event provider then reads F (stress, eigen-decomposition) before any later
        substep would have spread the overflow into v."""
        P = self.particles
        speed = P.v.norm(dim=1)  # [N]
        # one sum per particle is non-finite if any term is (inf − inf is NaN); a finite sum can only
        # overflow for entries near 1e37, a state that has diverged anyway. 3× cheaper than isfinite
        # per entry on the CPU.
        total = P.x.sum(1) + P.F.flatten(1).sum(1) + P.C.flatten(1).sum(1) + speed  # [N]
        bad = ~torch.isfinite(total) | (speed > self.grid.dx / dt)
        return bad.sum()

    def _frame_check(self, dt: float) -> tuple[int, int, int, int, int]:
        """(diverged particles, box escapes, slot overflows, pool overflows, pool rows used) of the
        frame, in one host read."""
        c = self.counts.long()
        values = torch.stack(
            [
                self._bad_particles(dt),
                c[COUNT_ESCAPED],
                c[COUNT_SLOT_OVERFLOW],
                c[COUNT_POOL_OVERFLOW],
                self.grid.rows_used().to(c.device),
            ]
        ).tolist()
        return tuple(int(v) for v in values)

    def _raise_diverged(self, dt: float, count: int) -> None:
        bound = self.cfl_dt()
        cause = (
            f"Δt = {dt:.3g}s is over the CFL bound {bound:.3g}s for this stiffness "
            f"(wave speed {self.wave_speed:.3g} m/s)"
            if dt > bound
            else "an extreme deformation or boundary velocity"
        )
        raise SimulationDiverged(
            f"simulation diverged at frame {self.frame} (t = {self.time:.4g}s): {count} of {len(self.particles)} "
            f"particles have a non-finite state (x, v, F or C) or an exploding velocity; likely cause: {cause}. "
            f"Lower sim.dt or set sim.adaptive_dt = true.",
            frame=self.frame,
            count=count,
            cause=cause,
        )
