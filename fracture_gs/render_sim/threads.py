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
from typing import Optional

import torch

from ..runtime import side_stream, stream_lane
from ..sim.providers import make_provider
from ..sim.providers.broadcast import BroadcastProvider, LeaderProvider, MemoryChannel
from ..sim.topology import save_history
from .comparison import ComparisonVideo
from .context import RunContext, ScheduleResult
from .painter import Painter
from .variant import run_variant


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
    ctx: RunContext, painter: Painter, metrics, stop: Optional[threading.Event] = None
) -> ScheduleResult:
    """Run `ctx.order` (leader first) at once on `ctx.device`, one thread each. The comparison video is composed
    beside them from the leader's first latch on. `stop`: set it to stop every variant at its next frame (Ctrl-C
    here sets it)."""
    order, cfg = list(ctx.order), ctx.cfg
    stop = stop if stop is not None else threading.Event()
    channel = MemoryChannel()
    frames: dict = {v: [] for v in order}
    done: dict = {}
    lines = _Lines(metrics)
    live: Optional[ComparisonVideo] = None

    def work(lane: int, variant: str) -> None:
        leader = lane == 0
        try:
            with _variant_scope(ctx.device, lane):
                provider = LeaderProvider(make_provider(cfg.topology), channel) if leader else None
                summary, history = run_variant(
                    ctx, variant, painter, lines, frames[variant],
                    provider=provider or BroadcastProvider(channel), stop=stop, position=lane,
                )  # fmt: skip
            done[variant] = ("done", summary, history)
            if summary.interrupted:
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
    interrupted, told = False, False
    try:
        while any(t.is_alive() for t in threads):
            try:
                for t in threads:
                    t.join(timeout=0.05)
                first = None if told else channel.first()
                if first is not None:  # the insets need the interface: compose from the first latch on
                    told = True
                    panels = [frames[v] for v in ctx.variants]
                    live = ComparisonVideo(
                        cfg, ctx.variants, panels, first, ctx.out_dir, ["ok"] * len(panels), ctx.frames_png
                    )
                    live.start_live(*panels)
            except KeyboardInterrupt:  # the variants stop at their next frame and return what they have
                interrupted = True
                stop.set()
        errors = [done[v][1] for v in order if v in done and done[v][0] == "error"]
        if errors:
            raise errors[0]
    except BaseException:
        if live is not None:
            live.abort()
        raise
    summaries = {v: done[v][1] for v in order if v in done}
    history = done[order[0]][2] if order[0] in done else None
    if history is not None:
        save_history(ctx.out_dir / "topology.npz", history)
    interrupted = interrupted or any(s.interrupted for s in summaries.values())
    return ScheduleResult(frames, summaries, history, interrupted, live)
