"""The comparison video of a render-sim run: comparison.mp4 and frames/compare_NNNN.png, the variants
side by side at matched frames with captions and fracture insets (`ComparisonVideo`), composed on a
thread beside the solver while the last variant runs (or, variants in threads, once every one has drawn
the frame), the rest with a pool after it.

Tried and dropped (bread paper preset on a GPU; docs/benchmarks/history-2026-11.md, third session):
composing in a spawned process fed the panels through a queue. Composing is not starved of the
interpreter lock (it is PNG and OpenCV work that releases it): the process left as much composing after
the last frame as the thread does, its start slowed the first variants, and its exit (torch's interpreter
teardown) came on top, so the run was longer in every interleaved pair.
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ..io.video import VideoWriter, save_png
from ..profiling import phases
from ..render import compose
from ..render.camera import frame_camera
from ..sim import Topology

LIVE_WINDOW = 2  # frames composed at once beside the solver (more took the interpreter lock from it)


class ComparisonVideo:
    """comparison.mp4 and frames/compare_NNNN.png: the variants side by side at matched frames, with
    captions and, after the latch, circular insets around the latched interface projected into each
    panel. A variant that stopped early (diverged, interrupted) holds its last frame, captioned with
    why. Frames go out in order. `start_live` composes them on the pool, `LIVE_WINDOW` at a time, while
    variants still run (frame i once every running variant has rendered it);
    `finish` stops it after its current frame and composes the rest with a pool of threads (numpy,
    OpenCV and the PNG encoder release the GIL), at most two per thread ahead of the encoder."""

    def __init__(self, cfg, variants, frame_lists, topology: Union[Topology, list, None], out_dir: Path, statuses):
        self.cfg, self.variants, self.frame_lists = cfg, list(variants), list(frame_lists)
        self.out_dir, self.statuses = out_dir, list(statuses)
        # a history: the inset follows the first event's interface
        self.topology: Optional[Topology] = topology[0] if isinstance(topology, list) else topology
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
            panels, region = [], None
            if topo is not None and latch_frame is not None and i >= latch_frame:  # one camera for all panels of i
                region = compose.interface_region(topo.point, topo.normal, 0.04, frame_camera(cfg, i))
            for frames in self.frame_lists:
                img = frames[min(i, len(frames) - 1)]
                if region is not None and i < len(frames):
                    cx, cy, r = region
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

    def _pump(self, available: int, window: int) -> None:
        """Submit frames below `available` while fewer than `window` are pending, then encode the oldest."""
        while self._submitted < available and len(self._pending) < window:
            self._pending.append(self._pool.submit(self.frame, self._submitted))
            self._submitted += 1
        if self._pending:
            frame = self._pending.popleft().result()
            with phases.section("encode"):
                self.video.write(frame)

    def start_live(self, *growing: list) -> None:
        """Compose frame i as soon as every list in `growing` (the frame lists of the variants still running:
        the last one when they run in turn, all of them in threads) holds it."""

        def work() -> None:
            try:
                while not self._stop.is_set():
                    available = min(len(f) for f in growing)
                    if self._submitted < available or self._pending:
                        self._pump(available, LIVE_WINDOW)
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
                self._pump(n, 2 * self._workers)
        finally:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self.video.close()


def compose_comparison(cfg, variants, frame_lists, topology: Union[Topology, list, None], out_dir: Path, statuses=None):
    """The comparison video of finished variants (`ComparisonVideo`)."""
    statuses = statuses or ["ok"] * len(variants)
    ComparisonVideo(cfg, variants, frame_lists, topology, out_dir, statuses).finish()
