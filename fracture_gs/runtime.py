"""Warp on first use, on torch's stream: the two things every kernel launcher in the package needs.

Importing `fracture_gs` changes nothing in the process: no Warp config is written, Warp is not
initialised and no file descriptor is touched. The first object that launches a kernel calls
`ensure_warp()`; kernel modules set their own compile options with `wp.set_module_options`
(forward-only kernels, `enable_backward=False`), so another Warp user in the same process, or
the differentiable path of this package, keeps Warp's defaults.

Every launch of the package names its stream: `warp_stream(device)`, the Warp wrapper of torch's current
CUDA stream (DESIGN.md, "Performance rules"): a kernel must never read a tensor before torch has finished
writing it. Torch's current stream is per thread; Warp's current stream is per device, shared by every
thread, so a launch that leaves its stream to Warp can land on another thread's stream (variants side by
side did: a graph launched into a stream another thread was capturing). `torch_stream(device)` also sets
Warp's current stream, for single-threaded code that leaves it implicit (the differentiable solver).
"""

from __future__ import annotations

import contextlib
import threading
from typing import TYPE_CHECKING, Optional

import warp as wp

if TYPE_CHECKING:
    import torch

_streams: dict[int, object] = {}


def ensure_warp() -> None:
    """Initialise Warp once (its time is the "warp init" row of `--profile`). The library leaves `wp.config` to
    the application (the CLI quiets Warp's start-up and module-load lines for its own process,
    `cli.devices._prepare_warp`)."""
    if not _initialised():
        import time

        from .profiling import phases

        start = time.perf_counter()
        wp.init()
        phases.note_startup("warp init", time.perf_counter() - start)


def _initialised() -> bool:
    from warp._src import context  # Warp 1.19 has no public `is_initialized`

    return context.runtime is not None


def warp_stream(device: str):
    """The Warp stream wrapping torch's current stream on `device` (None on the CPU), for `wp.launch(stream=)`
    and `wp.capture_launch(stream=)`: this thread's stream, whatever other threads launch meanwhile."""
    if not str(device).startswith("cuda"):
        return None
    import torch

    ts = torch.cuda.current_stream(device)
    key = ts.cuda_stream
    if key not in _streams:
        _streams[key] = wp.stream_from_torch(ts)
    return _streams[key]


def launch(kernel, dim, inputs: list, device: str) -> None:
    """`wp.launch` on `device`, on this thread's torch stream there (`warp_stream`): how the package launches."""
    wp.launch(kernel, dim=dim, inputs=inputs, device=device, stream=warp_stream(device))


def torch_stream(device: str):
    """Context in which Warp launches go to torch's current stream on `device` (no-op on the CPU)."""
    stream = warp_stream(device)
    if stream is None:
        return contextlib.nullcontext()
    return wp.ScopedStream(stream, sync_enter=False)


_side_streams: dict = {}
_lane = threading.local()

capture_lock = threading.RLock()
"""Held while a thread records a CUDA graph (Warp's or torch's capture): captures are thread-local, but
torch's `torch.cuda.graph` synchronizes the device before it starts, which would break a capture that
another thread has open. Every recording in the package takes it, so two never overlap."""


@contextlib.contextmanager
def stream_lane(lane: int):
    """`side_stream` calls of this thread inside the block use lane `lane`'s streams: variants simulated
    at once on one device, a thread each (`fracture_gs.render_sim.threads`), each get their own streams,
    so one's launches and captures never land on another's stream. Lane 0 is every thread's default."""
    before = getattr(_lane, "index", 0)
    _lane.index = int(lane)
    try:
        yield
    finally:
        _lane.index = before


def current_lane() -> int:
    """This thread's stream lane (`stream_lane`); 0 unless set."""
    return getattr(_lane, "index", 0)


def side_stream(device: str | torch.device, purpose: str = "simulate"):
    """One non-default torch stream per CUDA device, purpose and lane ("simulate": the simulators and
    benchmarks of the lane, as CUDA graphs cannot record the legacy default stream; "render": the
    render-sim worker that draws frames beside the solver; "record": the captures of `sim/recorded.py`;
    "main": a variant thread's own; "fork": `StreamFork`). Lanes (`stream_lane`) keep variants that run at
    once apart; the solver's run at CUDA's highest priority (`stream_priority`). Reusing them matters: torch
    caches a cuBLAS workspace per stream (32 MiB on Hopper), so a fresh pool stream per run held memory that only
    came back after torch had cycled through its 32 pooled streams (found by benchmarks/soak.py)."""
    import torch

    key = (str(torch.device(device)), purpose, current_lane())
    if key not in _side_streams:
        _side_streams[key] = torch.cuda.Stream(torch.device(device), priority=stream_priority(purpose))
    return _side_streams[key]


SOLVER_PURPOSES = frozenset(("simulate", "record", "fork"))
"""`side_stream` purposes whose work the next frame waits for: the substeps, the diagnostics' recorded graphs (replayed
on the solver's stream, recorded on their own) and the solver's forked launches."""


HIGHEST_PRIORITY = -64
"""A stream priority above any device's range: torch maps it to the highest the device has (a smaller number runs
first; 0, the default, is the lowest)."""


def stream_priority(purpose: str) -> int:
    """CUDA priority of a `side_stream`: the solver's streams at the highest, so the next frame's host read is not
    held up by the renderer's or the composer's kernels queued beside it on the device (the render thread draws frame
    n while the solver runs frame n + 1); every other stream at 0, torch's default and the lowest. Priorities order
    which ready blocks the device starts next; they change no kernel's work, so no number."""
    return HIGHEST_PRIORITY if purpose in SOLVER_PURPOSES else 0


_constants: dict = {}


def device_constant(values, dtype, device):
    """A small constant tensor on `device`, made once per (values, dtype, device): a tensor built from a Python
    list each frame is a pageable host-to-device copy that waits for the stream and cannot be recorded in a
    CUDA graph (DESIGN.md "Performance rules")."""
    import torch

    key = (tuple(values), dtype, str(device))
    if key not in _constants:
        _constants[key] = torch.tensor(key[0], dtype=dtype, device=device)
    return _constants[key]


_pool = None
_cpu_share: Optional[int] = None  # cores this process's kernels may split over (None: every core)


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity mask, not the machine's count)."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def share_cpu(cores: Optional[int]) -> Optional[int]:
    """Let `cpu_ranges` split a kernel over at most `cores` threads (None: the machine's cores), for a process
    that shares the machine with other workers of one run; returns the previous share. The ranges are bitwise
    the same result however many there are."""
    global _cpu_share
    before, _cpu_share = _cpu_share, cores
    return before


def cpu_ranges(n: int, min_chunk: int = 8192) -> list[tuple[int, int]]:
    """Ranges that split n particles over this process's cores (`share_cpu`; default every core) for a
    per-particle CPU kernel (Warp runs CPU kernels on one thread; a kernel with no atomics and no
    cross-particle reads can run as one launch per range, from several threads, with bitwise the same result)."""
    cores = _cpu_share if _cpu_share is not None else usable_cores()
    parts = max(1, min(cores, 8, n // min_chunk))
    step = -(-n // parts)
    return [(a, min(n, a + step)) for a in range(0, n, step)]


def range_views(arrays: list, a: int, b: int) -> list:
    """Views of `arrays` (Warp arrays of one length) over the particles [a, b): the arrays themselves when the range
    is all of them, as it is in a process with one core's share (a Warp slice is a new Python object, about 10 µs,
    and a CPU substep took about fifteen)."""
    if a == 0 and all(b == t.shape[0] for t in arrays):
        return list(arrays)
    return [t[a:b] for t in arrays]


def run_ranges(fn, ranges: list) -> None:
    """fn(a, b) for every range, concurrently when there are several (Warp's CPU launches release the GIL)."""
    global _pool
    if len(ranges) <= 1:
        for a, b in ranges:
            fn(a, b)
        return
    if _pool is None:
        from concurrent.futures import ThreadPoolExecutor

        _pool = ThreadPoolExecutor(max_workers=8, thread_name_prefix="fgs-cpu")
    for f in [_pool.submit(fn, a, b) for a, b in ranges]:
        f.result()


class StreamFork:
    """Launches that may run beside the current stream's (CUDA; a no-op on the CPU, where one thread runs
    every launch in order). The first `with fork:` after a join makes the fork's stream wait for everything
    issued so far on the current one (the fork); inside, torch's current stream is the fork's, so launches
    that name `warp_stream(device)` go there; `join()` makes the stream forked from wait for them. Under a
    graph capture the two become parallel paths of the graph (event edges), so small kernels that do not
    depend on each other overlap instead of each paying its launch gap and tail in turn. The fork's stream
    is its thread's lane's (`side_stream(device, "fork")`): a stream being captured by one thread must not
    receive another thread's launches."""

    def __init__(self, device: str):
        self.device = str(device)
        self._fork = None  # the fork's stream, from the first `with` after a join to the join
        self._main = None  # the stream forked from, until the join
        self._scope = None
        self.forks = 0  # forks opened so far (CUDA): tests check that launches went beside

    def open(self) -> None:
        """Fork here: what goes beside later (before the join) waits only for what was issued before this call,
        so launches issued on the current stream in between run beside it too, and are issued first."""
        if not self.device.startswith("cuda") or self._main is not None:
            return
        import torch

        self._main = torch.cuda.current_stream(self.device)
        self._fork = side_stream(self.device, "fork")
        self._fork.wait_stream(self._main)
        self.forks += 1

    def __enter__(self) -> StreamFork:
        if not self.device.startswith("cuda"):
            return self
        import torch

        self.open()
        self._scope = torch.cuda.stream(self._fork)
        self._scope.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        if self._scope is not None:
            self._scope.__exit__(*exc)
            self._scope = None

    def join(self) -> None:
        """The stream forked from waits for every launch made inside the fork since it was opened."""
        if self._main is not None:
            self._main.wait_stream(self._fork)
            self._main = self._fork = None


def import_in_background(*names: str) -> threading.Thread:
    """Import `names` on a daemon thread now, so a run that will need them later (scipy's modules at a fracture event:
    0.2–0.5 s on a slow host) finds them loaded instead of importing them on its critical thread. The import lock
    makes a later import of the same module wait for this one; a failure here is left for that import to raise.
    Start it only after any fork: a child forked mid-import could inherit a module lock held by no thread."""
    import importlib

    def work() -> None:
        for name in names:
            with contextlib.suppress(Exception):
                importlib.import_module(name)

    thread = threading.Thread(target=work, name="fgs-import", daemon=True)
    thread.start()
    return thread
