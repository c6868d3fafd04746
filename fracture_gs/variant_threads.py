"""The variants of one render-sim run at once on one device, a thread each (`--schedule threads`).

A variant's frame is mostly waiting: for its recorded substeps on the GPU, for the frame's one host
read, for the renderer. Run in turn, the device idles while the host prepares a frame and the host
idles while the device simulates it. In threads, one variant's host work can overlap another's kernels
(Warp's launches and graph replays, torch's kernels and every device read release the interpreter
lock; on the CPU Warp's kernels do too, one core each) — as long as the interpreter lock is not the
bottleneck itself. Measured (docs/benchmarks/history-2026-11.md, fifth session): the README's CPU main job a few
per cent faster on 2 cores; the bread paper preset on a GPU no faster in threads than in turn (its frames
are Python-bound: the threads only contend for the lock). Hence in turn stays the default.

The contract of the sequential run holds: the first variant with an event provider leads, and what it
latches reaches the others as it happens through a `MemoryChannel` (a follower at the end of its frame
f waits for the leader's frame f, as with `--devices`), so every variant uses the leader's topology at
the same frames as a replay of its saved history. On the CPU the per-frame metrics are bitwise those
of the run in turn (tests/test_variant_threads.py).

Each thread has its own stream lane (`runtime.stream_lane`): its own simulate, render, record and main
streams, so two variants never share a stream or record into one another's graph; recordings take
`runtime.capture_lock`. The comparison video is composed live once the leader's first topology is known
(the insets need it), frame i as soon as every variant has drawn it. metrics.jsonl stays live: each
variant writes its frame's row as a whole line under a lock, so rows of variants running at once
interleave (every row names its variant).
"""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path
from typing import Callable, Optional

import torch

from .runtime import side_stream, stream_lane
from .sim.providers import make_provider
from .sim.providers.broadcast import BroadcastProvider, LeaderProvider, MemoryChannel


class _Lines:
    """A text file that several threads append whole lines to (`write` then `flush`, as `run_variant` does)."""

    def __init__(self, fh):
        self.fh, self._lock = fh, threading.Lock()

    def write(self, text: str) -> None:
        with self._lock:
            self.fh.write(text)

    def flush(self) -> None:
        with self._lock:
            self.fh.flush()


def _variant_scope(device: str, lane: int):
    """This thread's lane, and on CUDA its own non-default stream (no variant thread touches
    the legacy default stream, which would wait on, and break, another thread's graph capture)."""
    stack = contextlib.ExitStack()
    stack.enter_context(stream_lane(lane))
    if device.startswith("cuda"):
        torch.cuda.set_device(torch.device(device))
        stack.enter_context(torch.cuda.stream(side_stream(device, "main")))
    return stack


def run_in_threads(
    run_variant: Callable,
    painter,
    cfg,
    gs,
    order: list,
    device: str,
    out_dir: Path,
    metrics,
    export=None,
    stop: Optional[threading.Event] = None,
    on_first_topology: Optional[Callable] = None,
) -> tuple[dict, dict, Optional[list], bool]:
    """Run `order` (leader first) at once on `device`, one thread each; returns (frames, summaries, the
    leader's history or None, interrupted) like `parallel.run_on_devices`. `run_variant` and `painter` come
    from the caller (the runner), whose module sits above this one. `on_first_topology(topology, frames)`
    is called once, from this thread, when the leader's first latch is known (the runner starts composing
    there). `stop`: set it to stop every variant at its next frame (Ctrl-C here sets it)."""
    stop = stop if stop is not None else threading.Event()
    channel = MemoryChannel()
    frames: dict = {v: [] for v in order}
    done: dict = {}
    lines = _Lines(metrics)

    def work(lane: int, variant: str) -> None:
        leader = lane == 0
        try:
            with _variant_scope(device, lane):
                provider = LeaderProvider(make_provider(cfg.topology), channel) if leader else None
                summary, history = run_variant(
                    cfg, gs, variant, device, out_dir, painter, None, lines, frames[variant], export,
                    provider=provider or BroadcastProvider(channel), stop=stop, position=lane,
                )  # fmt: skip
            done[variant] = ("done", summary, history)
            if summary.get("interrupted"):
                stop.set()
        except BaseException as exc:  # noqa: BLE001 - raised in the caller's thread
            stop.set()
            done[variant] = ("error", exc, None)
        finally:
            if leader:
                channel.close()  # followers past the leader's last frame stop waiting

    threads = [
        threading.Thread(target=work, args=(k, v), name=f"fgs-variant-{v}", daemon=True) for k, v in enumerate(order)
    ]
    for t in threads:
        t.start()
    interrupted, told = False, on_first_topology is None
    while any(t.is_alive() for t in threads):
        try:
            for t in threads:
                t.join(timeout=0.05)
            first = None if told else channel.first()
            if first is not None:
                told = True
                on_first_topology(first, frames)
        except KeyboardInterrupt:  # the variants stop at their next frame and return what they have
            interrupted = True
            stop.set()
    errors = [done[v][1] for v in order if v in done and done[v][0] == "error"]
    if errors:
        raise errors[0]
    summaries = {v: done[v][1] for v in order if v in done}
    history = done[order[0]][2] if order[0] in done else None
    interrupted = interrupted or any(s.get("interrupted") for s in summaries.values())
    return frames, summaries, history, interrupted
