"""The comparison video of a render-sim run: comparison.mp4 and frames/compare_NNNN.png, the variants
side by side at matched frames with captions and fracture insets (`ComparisonVideo`), composed beside
the solver while the last variant runs, either on a thread of the run's process or, on CUDA, in a
process of its own (`ComparisonProcess`).

Why a process on CUDA (docs/DESIGN.md "Performance rules"): composing is numpy, OpenCV and PNG work
that releases the interpreter lock in small pieces, and on a GPU run the solver's and the renderer's
threads hold that lock most of the time, so a compose thread spent ≈ 30 ms a frame waiting for it (9 ms
of work) and the run ended with a second of composing after the last frame was simulated (H200, bread
paper preset). A spawned process has its own interpreter; it starts when the run starts, so its imports
overlap with the first variants, and it receives each finished panel as a numpy array (≈ 0.26 MB).
On the CPU the solver and the renderer already use the cores, so the thread stays.
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import signal
import threading
import time
import traceback
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Optional

import numpy as np

from .errors import OutputError
from .io.video import VideoWriter, save_png
from .profiling import phases
from .render import compose
from .render.camera import frame_camera
from .sim import Topology


class ComparisonVideo:
    """comparison.mp4 and frames/compare_NNNN.png: the variants side by side at matched frames, with
    captions and, after the latch, circular insets around the latched interface projected into each
    panel. A variant that stopped early (diverged, interrupted) holds its last frame, captioned with
    why. Frames go out in order. `start_live` composes them one at a time on a worker thread while the
    last variant still runs (frame i once that variant has rendered it; the others are finished);
    `finish` stops it after its current frame and composes the rest with a pool of threads (numpy,
    OpenCV and the PNG encoder release the GIL), at most two per thread ahead of the encoder."""

    def __init__(self, cfg, variants, frame_lists, topology: Optional[Topology], out_dir: Path, statuses):
        self.cfg, self.variants, self.frame_lists = cfg, list(variants), list(frame_lists)
        self.out_dir, self.statuses = out_dir, list(statuses)
        if isinstance(topology, list):  # a history: the inset follows the first event's interface
            topology = topology[0]
        self.topology = topology
        self.video = VideoWriter(out_dir / "comparison.mp4", fps=cfg.render.fps)
        self._workers = max(1, min(8, os.cpu_count() or 1))
        self._pool = ThreadPoolExecutor(self._workers, thread_name_prefix="fgs-compose")
        self._pending: deque = deque()  # futures of submitted frames, oldest first
        self._submitted = 0
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._error: Optional[BaseException] = None

    def frame(self, i: int) -> np.ndarray:
        """Comparison frame i, also saved as frames/compare_NNNN.png."""
        cfg, topo = self.cfg, self.topology
        latch_frame = topo.latch_frame if topo is not None else None
        with phases.section("compose"):
            panels = []
            for frames in self.frame_lists:
                img = frames[min(i, len(frames) - 1)]
                if latch_frame is not None and i >= latch_frame and i < len(frames):
                    cx, cy, r = compose.interface_region(topo.point, topo.normal, 0.04, frame_camera(cfg, i))
                    if 0 <= cx < img.shape[1] and 0 <= cy < img.shape[0]:
                        r = float(np.clip(r, 8, cfg.render.inset_radius))
                        img = compose.add_inset(img, (cx, cy), r, cfg.render.inset_zoom)
                panels.append(img)
            caps = [
                compose.caption_text(v, i * cfg.frame_dt, i)
                if i < len(f)
                else f"{compose.caption_text(v, (len(f) - 1) * cfg.frame_dt, len(f) - 1)}  {st.split(':')[0]}"
                for v, f, st in zip(self.variants, self.frame_lists, self.statuses)
            ]
            frame = compose.side_by_side(panels, caps)
        with phases.section("io"):
            save_png(self.out_dir / "frames" / f"compare_{i:04d}.png", frame)
        return frame

    def _pump(self, available: int) -> None:
        """Submit frames below `available` (the window permitting), then encode the oldest in order."""
        while self._submitted < available and len(self._pending) < 2 * self._workers:
            self._pending.append(self._pool.submit(self.frame, self._submitted))
            self._submitted += 1
        if self._pending:
            frame = self._pending.popleft().result()
            with phases.section("encode"):
                self.video.write(frame)

    def start_live(self, live: list) -> None:
        """Compose frame i as soon as `live` (the running variant's frame list) holds it."""

        def work() -> None:  # one frame at a time: a pool here took the GIL from the solver's thread
            try:
                while not self._stop.is_set():
                    if self._submitted < len(live):
                        frame = self.frame(self._submitted)
                        self._submitted += 1
                        with phases.section("encode"):
                            self.video.write(frame)
                    else:
                        time.sleep(0.005)
            except BaseException as exc:  # noqa: BLE001 - raised by finish()
                self._error = exc

        self._thread = threading.Thread(target=work, name="fgs-compare", daemon=True)
        self._thread.start()

    def _stop_live(self) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None

    def abort(self) -> None:
        """Stop composing and close the video as it is (the caller writes another)."""
        self._stop_live()
        self._pool.shutdown(wait=True, cancel_futures=True)
        self.video.close()

    def finish(self, statuses=None) -> None:
        """Compose and write the frames not written yet, then close the video."""
        self._stop_live()
        if statuses is not None:
            self.statuses = list(statuses)
        try:
            if self._error is not None:
                raise self._error
            n = max(len(f) for f in self.frame_lists)
            while self._submitted < n or self._pending:
                self._pump(n)
        finally:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self.video.close()


def compose_comparison(cfg, variants, frame_lists, topology: Optional[Topology], out_dir: Path, statuses=None):
    """The comparison video of finished variants (`ComparisonVideo`)."""
    statuses = statuses or ["ok"] * len(variants)
    ComparisonVideo(cfg, variants, frame_lists, topology, out_dir, statuses).finish()


class ComparisonProcess:
    """`ComparisonVideo` in a spawned process, with the same `start_live` / `finish` / `abort` (and a
    `close` for a run that never composed). Spawned at construction (the run's start); `begin` hands it the
    variants, the topology and the panels so far, `start_live` forwards every new panel from a thread of
    this process. The worker's compose, io and encode seconds join this process's profile."""

    def __init__(self, cfg, out_dir: Path, profile: bool = False):
        ctx = multiprocessing.get_context("spawn")
        self._inbox, self._outbox = ctx.Queue(), ctx.Queue()
        self.proc = ctx.Process(
            target=_serve, args=(self._inbox, self._outbox, cfg, Path(out_dir), profile), name="fgs-compare"
        )
        self.proc.daemon = True
        self.proc.start()
        self.variants: list = []
        self._lists: list = []
        self._sent: list = []
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._begun = self._closed = False

    def begin(self, variants, frame_lists, topology: Optional[Topology], statuses, live: int) -> None:
        """Variants (panel order), their frame lists (list `live` still empty and growing), the topology."""
        self.variants, self._lists = list(variants), list(frame_lists)
        self._sent = [0] * len(self._lists)
        self._inbox.put(("begin", self.variants, topology, list(statuses), live))
        self._begun = True
        self._forward()

    def _forward(self) -> None:
        """Send the panels not sent yet, list by list (a finished variant's whole list before the live one's)."""
        for v, frames in enumerate(self._lists):
            while self._sent[v] < len(frames):
                self._inbox.put(("frame", v, frames[self._sent[v]]))
                self._sent[v] += 1

    def start_live(self, live: list) -> None:
        def work() -> None:
            while not self._stop.is_set():
                self._forward()
                time.sleep(0.005)

        self._thread = threading.Thread(target=work, name="fgs-compare-forward", daemon=True)
        self._thread.start()

    def _stop_forwarding(self) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None

    def finish(self, statuses=None) -> None:
        """Send the last panels, let the worker compose the rest and close the video; raises its error."""
        self._stop_forwarding()
        self._forward()
        self._end(("finish", None if statuses is None else list(statuses)))

    def abort(self) -> None:
        """Stop composing and close the video as it is (the caller writes another)."""
        self._stop_forwarding()
        self._end(("abort",), raise_error=False)

    def close(self) -> None:
        """End a worker that was never begun (a run of one variant, an interrupt before the last)."""
        if not self._closed:
            self._end(("abort",) if self._begun else ("quit",), raise_error=False)

    def _end(self, message, raise_error: bool = True) -> None:
        if self._closed:
            return
        self._closed = True
        self._inbox.put(message)
        reply = None
        while reply is None:
            try:
                reply = self._outbox.get(timeout=0.5)
            except queue.Empty:
                if not self.proc.is_alive():
                    reply = ("error", f"the comparison video worker exited with code {self.proc.exitcode}")
        self.proc.join(timeout=30)
        if reply[0] == "done":
            phases.merge(reply[1], reply[2])
        elif raise_error:
            raise OutputError(f"the comparison video could not be written: {reply[1].strip().splitlines()[-1]}")


def _serve(inbox, outbox, cfg, out_dir: Path, profile: bool) -> None:
    """The worker process: a `ComparisonVideo` fed from `inbox` (begin, frame, finish, abort, quit)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the run's process, which ends this one
    if profile:
        phases.enable()
    try:
        video, lists = None, []
        while True:
            msg = inbox.get()
            if msg[0] == "begin":
                variants, topology, statuses, live = msg[1:]
                lists = [[] for _ in variants]
                video = ComparisonVideo(cfg, variants, lists, topology, out_dir, statuses)
                video.start_live(lists[live])
            elif msg[0] == "frame":
                lists[msg[1]].append(msg[2])
            elif msg[0] == "finish":
                video.finish(msg[1])
                break
            elif msg[0] == "abort":
                if video is not None:
                    video.abort()
                break
            else:  # quit
                break
        outbox.put(("done", dict(phases.seconds), dict(phases.calls)))
    except BaseException:  # noqa: BLE001 - reported to the run's process
        outbox.put(("error", traceback.format_exc()))
