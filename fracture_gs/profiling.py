"""Where a run spends its time, by phase (`fracture-gs render-sim --profile`).

`phases.section("render")` times a block into the named phase, from any thread; with profiling off
it costs one attribute test. Phases run concurrently (the renderer works on frame n while the
solver runs frame n + 1), so their busy times can add up to more than the wall time; the report
shows both. On CUDA, `enable(sync_device=...)` synchronises the calling thread's current stream at
every section boundary, so GPU work is charged to the phase that launched it (a profiled run is a
little slower). Only that stream: a device-wide sync would make the renderer's thread wait for the
solver's queued substeps and the solver for the renderer's frame, a serialisation the unprofiled run
does not have (each worker draws on its own stream, `runtime.side_stream(device, "render")`); and the threads'
syncs do not wait for each other, only for a thread recording a CUDA graph (`SyncGate`).

Start-up has rows of its own (STARTUP), noted with `phases.note_startup`, which works with the timer off, since
most of start-up happens before a run enables it: "imports", the process's start to the run (the
interpreter, torch, Warp and the package loading, the flag and config checks: noted by the CLI, which knows
the run is the process's purpose), "warp init" (`wp.init()`, noted by `runtime.ensure_warp`) and "module
loads" (Warp kernel modules loaded during the run, each from the kernel cache or compiled: the CLI's Warp
logger reads Warp's own load lines). The next report shows them and forgets them.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time

PHASES = ("setup", "simulate", "diagnostics", "render", "compose", "encode", "io")
STARTUP = ("imports", "warp init", "module loads")
"""Start-up rows of the report, before the phases: the first two happen before the run, module loads inside it."""


def process_seconds() -> float | None:
    """Seconds since this process started (Linux: its start time in /proc against the boot clock, 10 ms
    steps), or None where that is not known."""
    try:
        with open("/proc/self/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()  # after the command name, which may hold spaces
        started = int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22, starttime: ticks since boot
        return max(0.0, time.clock_gettime(time.CLOCK_BOOTTIME) - started)
    except (OSError, ValueError, IndexError, AttributeError):
        return None


class SyncGate:
    """The profiler's stream syncs against CUDA graph recordings: any number of threads may sync at once (each waits
    for its own stream only, so one thread's wait must not hold up another's), but none while a thread records a
    graph (a sync from another thread during a capture is a CUDA error; the renderer's thread once ended a profiled
    run that way). A recording waits for the syncs under way and holds off new ones meanwhile; the recording thread
    itself may sync (its own sections), as it may record again inside a recording."""

    def __init__(self):
        self._cond = threading.Condition()
        self._syncs = 0  # syncs under way, from any thread but the recording one
        self._owner = None  # the thread recording, while one does
        self._depth = 0  # its nested recordings
        self._waiting = 0  # recordings waiting for the syncs under way: new syncs wait behind them

    @contextlib.contextmanager
    def shared(self):
        counted = threading.get_ident() != self._owner  # only this thread can make itself the owner
        if counted:
            with self._cond:
                while self._owner is not None or self._waiting:
                    self._cond.wait()
                self._syncs += 1
        try:
            yield
        finally:
            if counted:
                with self._cond:
                    self._syncs -= 1
                    self._cond.notify_all()

    @contextlib.contextmanager
    def exclusive(self):
        me = threading.get_ident()
        with self._cond:
            if self._owner != me:
                self._waiting += 1
                while self._owner is not None or self._syncs:
                    self._cond.wait()
                self._waiting -= 1
                self._owner = me
            self._depth += 1
        try:
            yield
        finally:
            with self._cond:
                self._depth -= 1
                if self._depth == 0:
                    self._owner = None
                self._cond.notify_all()


class PhaseTimer:
    """Busy seconds per phase, summed over threads, plus the wall time of the whole run."""

    def __init__(self):
        self.enabled = False
        self.sync_device = None
        self._lock = threading.Lock()
        self._gate = SyncGate()  # syncs side by side, none while a thread records a CUDA graph
        self._local = threading.local()
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self.startup: dict[str, list] = {}  # name -> [seconds, count, compiled] (STARTUP), until reported
        self._t0 = None

    def enable(self, sync_device=None) -> None:
        self.enabled, self.sync_device = True, sync_device
        self.seconds, self.calls = {}, {}
        self._t0 = time.perf_counter()

    def disable(self) -> None:
        self.enabled = False

    def note_startup(self, name: str, seconds: float, compiled: bool = False) -> None:
        """Add `seconds` of start-up work to row `name` (STARTUP; `compiled`: a module load that compiled rather
        than came from the kernel cache). Noted with profiling on or off; the next report shows it."""
        with self._lock:
            row = self.startup.setdefault(name, [0.0, 0, 0])
            row[0] += seconds
            row[1] += 1
            row[2] += int(compiled)

    def _sync(self) -> None:
        if self.sync_device is not None:
            import torch

            with self._gate.shared():
                torch.cuda.current_stream(self.sync_device).synchronize()

    @contextlib.contextmanager
    def capturing(self):
        """Hold off the profiler's device syncs from every thread while this thread records a CUDA
        graph (a device-wide sync during a capture is an error: the renderer's thread ended a profiled
        run that way). Free when profiling is off."""
        if self.sync_device is None or not self.enabled:
            yield
            return
        with self._gate.exclusive():
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

    def merge(self, seconds: dict, calls: dict) -> None:
        """Add another process's busy seconds and calls per phase (a worker of `render-sim`'s processes)."""
        with self._lock:
            for name, value in seconds.items():
                self.seconds[name] = self.seconds.get(name, 0.0) + value
                self.calls[name] = self.calls.get(name, 0) + calls.get(name, 0)

    def report(self) -> str:
        """A Markdown table: phase, busy seconds, share of the wall time, calls; the start-up rows first (those
        before the run have no share of its wall time). The start-up rows are forgotten once reported."""
        wall = time.perf_counter() - self._t0 if self._t0 is not None else 0.0
        names = [p for p in PHASES if p in self.seconds] + sorted(set(self.seconds) - set(PHASES))
        with self._lock:
            startup, self.startup = self.startup, {}
        before = sum(startup[p][0] for p in STARTUP[:2] if p in startup)
        lines = [
            f"wall time {wall:.2f} s (phases overlap: rendering runs beside the solver, workers beside this process)"
            + (f", after {before:.2f} s of start-up" if before else ""),
            "",
            "| phase | busy s | % of wall | calls |",
            "|---|---:|---:|---:|",
        ]
        for p in (p for p in STARTUP if p in startup):
            seconds, count, compiled = startup[p]
            if p == "module loads":  # inside the run: part of the phase that first launched each module
                label = f"{p} ({count - compiled} cached, {compiled} compiled)"
                share = f"{100.0 * seconds / wall:.0f}" if wall > 0 else "0"
            else:
                label, share = p, "before the run"
            lines.append(f"| {label} | {seconds:.2f} | {share} | {count} |")
        for p in names:
            share = 100.0 * self.seconds[p] / wall if wall > 0 else 0.0
            lines.append(f"| {p} | {self.seconds[p]:.2f} | {share:.0f} | {self.calls[p]} |")
        return "\n".join(lines) + "\n"


phases = PhaseTimer()
"""The process's phase timer (off until `phases.enable()`)."""
