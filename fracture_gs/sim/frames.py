"""`FrameRunner`: a frame of the solver, held by its `Simulator` (`sim.runner`).

A frame is a whole number of substeps ending exactly on the frame time, recorded once as a CUDA graph and replayed
(or launched on the CPU), then one host read — divergence, particles that left the grid work's box, slot and pool
overflows — that may roll the frame back and redo it, and the fracture event provider, which may latch again
(repeated fracture). The runner keeps the graph cache, the saved frame-start state and the redo policy (the slack
the boxes grow by, the redone frames and the overflows counted); the simulator keeps the state and the substep.
"""

from __future__ import annotations

import math
import weakref
from typing import Optional

import torch
import warp as wp

from ..errors import SimulationDiverged
from ..profiling import phases
from ..runtime import capture_lock, side_stream, warp_stream
from .particles import SimulationError
from .storage import COUNT_ESCAPED, COUNT_POOL_OVERFLOW, COUNT_SLOT_OVERFLOW


class FrameRunner:
    """Frames of substeps with checks and redo, for simulator `sim` (held weakly)."""

    MAX_TRIES = 8

    def __init__(self, sim):
        self.sim = weakref.proxy(sim)  # the simulator owns its runner: no reference cycle
        self.graph = None  # CUDA: the recorded substep
        self.graph_key_value = None  # `graph_key()` when it was recorded
        self._cuda_stream = None
        self._saved = None  # frame-start state for a redo (`advance`)
        self.box_slack = 0  # extra cells on the grid work's box; grows when a frame had to be redone
        self.frame_redos = 0
        self.slot_overflow = 0  # deposits that found no free slot, in the last frame
        self.slot_overflow_total = 0
        self.pool_overflow = 0  # pool insertions that failed in the last accepted frame

    def set_clock(self, dt: float, times: list) -> list:
        """Write a frame's clock table (Δt, substep times, region activity); returns the activity flags. A clock
        whose buffers moved drops the recorded substep."""
        sim = self.sim
        on, value = sim.boundaries.region_table(times, dt)
        if sim.clock.set(dt, times, on, value):
            self.graph = None
        return on

    def graph_key(self) -> tuple:
        """Everything a recorded substep bakes in besides the clock: a change means recording again. The
        simulator's routing and settings, then each storage's buffers and launch sizes (the slot storage's always:
        it holds the dense grid; the boxes' while they hold the fields)."""
        sim = self.sim
        release = sim.topology.release_events if sim.topology else 0
        common = (sim.multifield, sim.latched, sim.n_fragments, sim.normal_mode, release, sim.record_contact)
        common += (sim.cfg.wall_cells, sim.clock.capacity, sim.options.concurrent)
        return common + (sim.slots.graph_key(), sim.box_storage.graph_key() if sim.boxed else None)

    def run_substeps(self, n: int, dt: float, start: float) -> None:
        """The frame's n substeps: on CUDA one recorded substep (a CUDA graph on the simulator's own
        stream) replayed n times, recorded again when something it bakes in changed; else launches."""
        sim = self.sim
        times, t = [], start
        for _ in range(n):
            times.append(t)
            t += dt
        on = self.set_clock(dt, times)
        sim.grid.reset_claims()  # claims last one frame
        graphs = sim.options.use_graphs and sim.device.startswith("cuda") and sim.frame > 0
        if graphs and (self.graph is None or self.graph_key() != self.graph_key_value):
            with sim._stream_scope(), capture_lock, phases.capturing():
                with wp.ScopedCapture(
                    device=sim.device, stream=warp_stream(sim.device), force_module_load=False
                ) as capture:
                    sim.substep_launches(None)
            self.graph, self.graph_key_value = capture.graph, self.graph_key()
        with sim._stream_scope():
            for i in range(n):
                if graphs:
                    wp.capture_launch(self.graph, stream=warp_stream(sim.device))
                else:
                    sim.substep_launches(on, i)
        for _ in range(n):
            sim.time += dt
            sim.substeps += 1

    def frame_substeps(self, frame_dt: float, vmax: Optional[float] = None) -> tuple[int, float]:
        """(n, Δt) with n·Δt = frame_dt exactly and Δt ≤ cfg.dt (and the CFL bound if adaptive;
        `vmax`, the largest particle speed, is read from the device when not given)."""
        sim = self.sim
        dt = sim.cfg.dt
        if sim.cfg.adaptive_dt:
            if vmax is None:
                vmax = float(sim.particles.v.norm(dim=1).max())
            if math.isfinite(vmax):
                dt = min(dt, sim.cfl_dt(vmax))
        n = max(1, math.ceil(frame_dt / dt - 1e-9))
        if n > sim.cfg.max_substeps_per_frame:
            raise SimulationError(
                f"a frame of {frame_dt}s needs {n:,} substeps of {dt:.3g}s (the CFL bound of the material's wave "
                f"speed at Δx = {sim.grid.dx:.3g} m), over sim.max_substeps_per_frame = "
                f"{sim.cfg.max_substeps_per_frame:,}; lower material.E (or raise sim.max_substeps_per_frame)."
            )
        return n, frame_dt / n

    def advance(self, frame_dt: float) -> int:
        """Simulate one frame: n substeps, then the divergence check and the event provider.

        The frame runs on grid work fitted at its start (`Simulator.fit_active_box`). If a particle's stencil left
        it (P2G counts it) or the pool of multi-fragment nodes filled up, the frame is rolled back and redone: with
        more slack (after the second escape the storage may take the whole grid, where nothing can escape; the
        per-fragment boxes only grow their slack) or with a pool twice as large. One host read per try for the
        fit and one for the frame's check (per-fragment boxes add the fit's two). On CUDA the frame runs on the
        simulator's own stream (graphs are recorded on a non-default stream), ordered after the caller's current
        stream and before it again at the end."""
        sim = self.sim
        if not sim.device.startswith("cuda"):
            return self._advance(frame_dt)
        if self._cuda_stream is None:
            self._cuda_stream = side_stream(sim.device)
        caller = torch.cuda.current_stream(sim.device)
        self._cuda_stream.wait_stream(caller)
        with torch.cuda.stream(self._cuda_stream):
            n = self._advance(frame_dt)
        caller.wait_stream(self._cuda_stream)
        return n

    def _advance(self, frame_dt: float) -> int:
        sim = self.sim
        if sim.substeps == 0:
            self.poll_provider()  # an oracle may latch before the first substep
        start, substeps0 = sim.time, sim.substeps
        self.save_state()
        escapes = 0
        for attempt in range(self.MAX_TRIES):
            if escapes >= 2 and sim.storage.whole_grid():
                vmax = None  # the whole grid: nothing to fit (the substeps read max |v| themselves)
            else:
                vmax = sim.fit_active_box(frame_dt)  # the frame's one host read also gives max |v|
            n, dt = self.frame_substeps(frame_dt, vmax)
            sim.dt = dt
            sim.counts[COUNT_ESCAPED:] = 0
            self.run_substeps(n, dt, start)
            bad, escaped, slot_overflow, pool_overflow, rows = self.frame_check(dt)
            sim.slots.frame_done(rows)
            if (escaped == 0 and pool_overflow == 0) or attempt == self.MAX_TRIES - 1:
                break
            self.restore_state()
            sim.time, sim.substeps = start, substeps0
            if escaped:
                escapes += 1
                self.box_slack = 2 * self.box_slack + 2
            if pool_overflow:
                sim.slots.grow_pool()
            self.frame_redos += 1
        self.slot_overflow, self.pool_overflow = slot_overflow, pool_overflow
        self.slot_overflow_total += slot_overflow
        sim.time = start + frame_dt  # end exactly on the frame time (no drift from summing Δt)
        sim.frame += 1
        if bad:
            self.raise_diverged(dt, bad)
        self.poll_provider()
        if sim._diagnostics is not None:
            sim._diagnostics.on_frame()
        return n

    def save_state(self) -> None:
        """Copy what a frame can change into buffers made once (device copies, no sync)."""
        sim = self.sim
        P, g = sim.particles, sim.grid
        keep = {"stats": g.contact_stats, "pair_stats": g.pair_stats, "counts": sim.counts}
        if self._saved is None:
            self._saved = {k: torch.empty_like(getattr(P, k)) for k in sim.MUTABLE}
            self._saved.update({k: torch.empty_like(t) for k, t in keep.items()})
        for k in sim.MUTABLE:
            self._saved[k].copy_(getattr(P, k))
        for k, t in keep.items():
            self._saved[k].copy_(t)

    def restore_state(self) -> None:
        sim = self.sim
        P, g = sim.particles, sim.grid
        for k in sim.MUTABLE:
            getattr(P, k).copy_(self._saved[k])
        g.contact_stats.copy_(self._saved["stats"])
        g.pair_stats.copy_(self._saved["pair_stats"])
        sim.counts.copy_(self._saved["counts"])

    def poll_provider(self) -> None:
        """Ask the event provider for a new topology (it returns one per fracture event) and latch it."""
        sim = self.sim
        if sim.provider is not None:
            topology = sim.provider(sim)
            if topology is not None:
                sim.latch(topology)

    def bad_particles(self, dt: float) -> torch.Tensor:
        """Particles with a non-finite x, v, F or C, or faster than Δx/Δt (a device count).

        F and C are checked too: the last substep of a frame can overflow F while x and v are still
        finite, and the event provider then reads F (stress, eigen-decomposition) before any later
        substep would have spread the overflow into v."""
        sim = self.sim
        P = sim.particles
        speed = P.v.norm(dim=1)  # [N]
        # one sum per particle is non-finite if any term is (inf − inf is NaN); a finite sum can only
        # overflow for entries near 1e37, a state that has diverged anyway. 3× cheaper than isfinite
        # per entry on the CPU.
        total = P.x.sum(1) + P.F.flatten(1).sum(1) + P.C.flatten(1).sum(1) + speed  # [N]
        bad = ~torch.isfinite(total) | (speed > sim.grid.dx / dt)
        return bad.sum()

    def frame_check(self, dt: float) -> tuple[int, int, int, int, int]:
        """(diverged particles, box escapes, slot overflows, pool overflows, pool rows used) of the
        frame, in one host read."""
        sim = self.sim
        c = sim.counts.long()
        values = torch.stack(
            [
                self.bad_particles(dt),
                c[COUNT_ESCAPED],
                c[COUNT_SLOT_OVERFLOW],
                c[COUNT_POOL_OVERFLOW],
                sim.grid.rows_used().to(c.device),
            ]
        ).tolist()
        return tuple(int(v) for v in values)

    def raise_diverged(self, dt: float, count: int) -> None:
        sim = self.sim
        bound = sim.cfl_dt()
        cause = (
            f"Δt = {dt:.3g}s is over the CFL bound {bound:.3g}s for this stiffness "
            f"(wave speed {sim.wave_speed:.3g} m/s)"
            if dt > bound
            else "an extreme deformation or boundary velocity"
        )
        raise SimulationDiverged(
            f"simulation diverged at frame {sim.frame} (t = {sim.time:.4g}s): {count} of {len(sim.particles)} "
            f"particles have a non-finite state (x, v, F or C) or an exploding velocity; likely cause: {cause}. "
            f"Lower sim.dt or set sim.adaptive_dt = true.",
            frame=sim.frame,
            count=count,
            cause=cause,
        )
