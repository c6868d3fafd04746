"""Worker processes for `render-sim`'s processes schedule on one device, forked at the run's start.

A spawned worker starts a new interpreter: it imports torch, Warp and the package again (about 3.5 s of one
core on a 2-core machine, as long as the parent's own imports), which a CPU run of a few tens of seconds
cannot spare. A forked worker has them already. Forking is safe only while the parent has not yet run a
parallel torch op: GNU OpenMP's thread pool does not survive a fork, and a child that enters a parallel region
the parent had used hangs there. So `ForkedWorkers` forks at the start of `run_render_sim`, before the scene is
prepared, and each child waits for its job (the prepared `RunContext` and its variants, sent through a queue).

Each child checks first that OpenMP works in it (one parallel reduction) and says so; the parent waits for every
child's word (`READY_SECONDS`) before it runs its own variants. A child that does not answer is taken as a
broken fork: the workers are stopped and the schedule spawns fresh ones instead (`multi_device`), so the run
goes on, slower, and says why. A job names the function the child runs (`multi_device._worker`), so this module
imports nothing of the scheduler's.

On a GPU a child cannot use CUDA once its parent started the driver (torch's device query does, Warp's start-up
does, and so does looking up gsplat's build). The CLI checks a processes run's device through NVML and leaves Warp
unstarted (`cli.devices.fork_safe_cuda_checks`), the run forks before it looks for gsplat, `cuda_untouched` refuses
to fork where torch or Warp has started CUDA, and each child proves CUDA works in it before it reports ready; one
that cannot says why at once (`ForkedWorkers.broken`), and the run spawns fresh workers instead.
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import signal
import sys
from typing import Callable, Optional

import torch

READY_SECONDS = 10.0
"""How long the parent waits for every forked child to prove OpenMP works in it before it gives up on them (a
healthy child answers within milliseconds of its job: the job's tensors travel in shared memory)."""


def can_fork() -> bool:
    """Whether this platform forks (Linux does; macOS's default and Windows spawn)."""
    return "fork" in multiprocessing.get_all_start_methods() and sys.platform.startswith("linux")


def cuda_untouched() -> bool:
    """Whether this process has left the CUDA driver unstarted, as far as torch and Warp can tell, so children
    forked now may use CUDA (`torch.cuda.is_available()` without NVML starts it unseen: the children check)."""
    if torch.cuda.is_initialized():
        return False
    from warp._src import context  # Warp 1.19 has no public `is_initialized`

    return context.runtime is None or not context.runtime.cuda_devices


def _start_cuda(device: str, gsplat: bool) -> Optional[str]:
    """Start CUDA and Warp on `device` in this child (seconds on a GPU host), and with `gsplat` (the `auto` backend)
    load gsplat's CUDA code where it is built already, or, where it is not (the parent starts its build after the
    fork), draw this child's frames with the torch rasterizer; returns the sentence why CUDA does not work here, or
    None (the parent started the CUDA driver before the fork after all: a library caller)."""
    try:
        torch.ones(1, device=device).sum().item()
        from ..runtime import ensure_warp

        ensure_warp()
    except Exception as exc:  # noqa: BLE001 - any failure means no CUDA here: the parent spawns instead
        return f"CUDA does not work in a forked worker ({str(exc).splitlines()[0]})"
    if gsplat:
        from ..render.warm_up import draw_without_gsplat, gsplat_needs_compile

        if gsplat_needs_compile():  # the parent builds it now, beside the run: this worker draws with torch
            draw_without_gsplat("gsplat was being built when this worker started")
            return None
        try:
            from gsplat.cuda import _backend  # noqa: F401 - loads the build; the first frame would anyway
        except Exception:  # noqa: BLE001 - the first frame meets it again and reports it there
            pass
    return None


def _child(jobs, ready, stop, results, device: str, gsplat: bool = False, parent: Optional[int] = None) -> None:
    """A forked worker: for a CUDA run start CUDA and Warp at once (beside the parent's scene preparation), wait
    for a job (fn, slot, threads, args, kwargs), prove OpenMP works here on `threads` torch threads (and, for a
    CUDA run, that CUDA did start), then run fn(*args, stop=stop, results=results, **kwargs). `parent`: the pid of
    the process that forked it, taken before the fork (a child that asked only once running would take the init
    process for its parent if the parent was killed first, and wait forever)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)  # not the parent's handler, which sets its own event
    parent = os.getppid() if parent is None else parent
    try:
        broken = _start_cuda(device, gsplat) if device.startswith("cuda") else None
        while True:  # a parent killed before it sent the job (SIGKILL, out of memory) leaves no child waiting
            try:
                job = jobs.get(timeout=1.0)
                break
            except queue.Empty:
                if os.getppid() != parent:
                    return
        if job is None:  # the run chose another schedule
            return
        fn, slot, threads, args, kwargs = job
        torch.set_num_threads(threads)
        torch.ones(1 << 16, dtype=torch.float64).sum()  # a parallel region: hangs here if the fork broke OpenMP
        ready.put((slot, broken))
        if broken is not None:
            return
    except KeyboardInterrupt:  # Ctrl-C before the run began: the parent reports it
        return
    fn(*args, stop=stop, results=results, **kwargs)


class ForkedWorkers:
    """`n` worker processes forked now, each waiting for one job (`start`); `close` ends the unused ones. The
    `stop` event and `results` queue are the ones `multi_device.run_on_devices` reads."""

    def __init__(self, n: int, device: str = "cpu", gsplat: bool = False):
        mp = torch.multiprocessing.get_context("fork")
        self.stop, self.results, self.ready = mp.Event(), mp.Queue(), mp.Queue()
        self.jobs = [mp.Queue() for _ in range(n)]
        sys.stdout.flush()  # a child flushes its copy of unwritten output at exit: write it once, now
        sys.stderr.flush()
        self.procs = [
            mp.Process(
                target=_child,
                args=(q, self.ready, self.stop, self.results, str(device), gsplat, os.getpid()),
                name=f"fgs-{str(device).replace(':', '')}-{i + 1}",
                daemon=True,
            )
            for i, q in enumerate(self.jobs)
        ]
        for p in self.procs:
            p.start()
        self.used: list = []
        self.broken: Optional[str] = None  # why `start` gave up on the children, if it did

    def __len__(self) -> int:
        return len(self.procs)

    def start(self, fn: Callable, jobs: list[tuple]) -> Optional[list]:
        """Hand each job (slot, threads, args, kwargs) to a child, which runs fn(*args, stop=, results=, **kwargs)
        (`fn` a module-level function: it travels by name) on `threads` torch threads; the other children end.
        Returns the children running them once each has proved OpenMP works in it, or None if one did not within
        `READY_SECONDS` (then every child is stopped and the caller spawns workers instead)."""
        if len(jobs) > len(self.procs):
            raise ValueError(f"{len(jobs)} jobs for {len(self.procs)} forked workers")
        for q, job in zip(self.jobs, jobs):
            q.put((fn, *job))
        self.used = self.procs[: len(jobs)]
        self.close()
        waiting = {job[0] for job in jobs}
        self.broken = None
        try:
            while waiting:
                slot, broken = self.ready.get(timeout=READY_SECONDS)
                if broken is not None:
                    self.broken = broken
                    break
                waiting.discard(slot)
        except queue.Empty:
            self.broken = f"the forked workers did not start within {READY_SECONDS:.0f} s (OpenMP in a forked process)"
        if self.broken is not None:
            self.terminate()
            return None
        return self.used

    def close(self) -> None:
        """End the children that got no job (they exit at once)."""
        for q, p in zip(self.jobs, self.procs):
            if p not in self.used:
                q.put(None)
        for p in self.procs:
            if p not in self.used:
                p.join(timeout=5)

    def terminate(self) -> None:
        """Stop every child now (a broken fork, or the run failed before it handed out its jobs)."""
        for p in self.procs:
            if p.is_alive():
                p.terminate()
        for p in self.procs:
            p.join(timeout=5)
        self.used = []
