"""Where a run spends its time, by phase (`fracture-gs render-sim --profile`).

`phases.section("render")` times a block into the named phase, from any thread; with profiling off
it costs one attribute test. Phases run concurrently (the renderer works on frame n while the
solver runs frame n + 1), so their busy times can add up to more than the wall time; the report
shows both. On CUDA, `enable(sync_device=...)` synchronises the calling thread's current stream at
every section boundary, so GPU work is charged to the phase that launched it (a profiled run is a
little slower). Only that stream: a device-wide sync would make the renderer's thread wait for the
solver's queued substeps and the solver for the renderer's frame, a serialisation the unprofiled run
does not have (each worker draws on its own stream, `runtime.side_stream(device, "render")`).
"""

from __future__ import annotations

import contextlib
import threading
import time

PHASES = ("setup", "simulate", "diagnostics", "render", "compose", "encode", "io")


class PhaseTimer:
    """Busy seconds per phase, summed over threads, plus the wall time of the whole run."""

    def __init__(self):
        self.enabled = False
        self.sync_device = None
        self._lock = threading.Lock()
        self._device = threading.RLock()  # no device-wide sync while a thread records a CUDA graph
        self._local = threading.local()
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._t0 = None

    def enable(self, sync_device=None) -> None:
        self.enabled, self.sync_device = True, sync_device
        self.seconds, self.calls = {}, {}
        self._t0 = time.perf_counter()

    def disable(self) -> None:
        self.enabled = False

    def _sync(self) -> None:
        if self.sync_device is not None:
            import torch

            with self._device:
                torch.cuda.current_stream(self.sync_device).synchronize()

    @contextlib.contextmanager
    def capturing(self):
        """Hold off the profiler's device syncs from every thread while this thread records a CUDA
        graph (a device-wide sync during a capture is an error: the renderer's thread ended a profiled
        run that way). Free when profiling is off."""
        if self.sync_device is None or not self.enabled:
            yield
            return
        with self._device:
            yield

    @contextlib.contextmanager
    def section(self, name: str):
        """Charge the block's time to `name`; a section inside another is charged to itself only."""
        if not self.enabled:
            yield
            return
        stack = getattr(self._local, "stack", None)
        if stack is None:
            stack = self._local.stack = []
        self._sync()
        frame = [time.perf_counter(), 0.0]
        stack.append(frame)
        try:
            yield
        finally:
            self._sync()
            stack.pop()
            dt = time.perf_counter() - frame[0]
            if stack:
                stack[-1][1] += dt
            with self._lock:
                self.seconds[name] = self.seconds.get(name, 0.0) + dt - frame[1]
                self.calls[name] = self.calls.get(name, 0) + 1

    def report(self) -> str:
        """A Markdown table: phase, busy seconds, share of the wall time, calls."""
        wall = time.perf_counter() - self._t0 if self._t0 is not None else 0.0
        names = [p for p in PHASES if p in self.seconds] + sorted(set(self.seconds) - set(PHASES))
        lines = [
            f"wall time {wall:.2f} s (phases overlap: rendering runs beside the solver)",
            "",
            "| phase | busy s | % of wall | calls |",
            "|---|---:|---:|---:|",
        ]
        for p in names:
            share = 100.0 * self.seconds[p] / wall if wall > 0 else 0.0
            lines.append(f"| {p} | {self.seconds[p]:.2f} | {share:.0f} | {self.calls[p]} |")
        return "\n".join(lines) + "\n"


phases = PhaseTimer()
"""The process's phase timer (off until `phases.enable()`)."""
