"""The comparison video of a render-sim run: comparison.mp4 and (`frames_png`) frames/compare_NNNN.png, the
variants side by side at matched frames with captions and fracture insets (`ComparisonVideo`), composed on a
thread beside the solver while the last variant runs (or, variants in threads, once every one has drawn
the frame), the rest with a pool after it. Each frame is composed as torch ops on the panels' device
(`render.compose_torch`: on CUDA the variants' frames are still there, `painter.DrawnFrame`) and copied to the
host once; a writer thread encodes it (`writer.FrameWriter`).

Tried and dropped (bread paper preset on a GPU; docs/benchmarks/history-2026-11.md, third session):
composing in a spawned process fed the panels through a queue. Composing is not starved of the
interpreter lock (it is PNG and OpenCV work that releases it): the process left as much composing after
the last frame as the thread does, its start slowed the first variants, and its exit (torch's interpreter
teardown) came on top, so the run was longer in every interleaved pair.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Optional, Union

import numpy as np
import torch

from ..io.video import save_png
from ..profiling import phases
from ..render import compose
from ..render.camera import frame_camera
from ..render.compose_torch import Inset, compose_row
from ..runtime import side_stream
from ..sim import Topology
from .writer import FrameWriter

LIVE_WINDOW = 2  # frames composed at once beside the solver (more took the interpreter lock from it)
PANEL_GAP = 4  # px between the panels of a comparison frame (`compose_row`'s gap)


def check_video_size(cfg, variants) -> None:
    """Before the run: the comparison frame (the variants' panels side by side) fits the video encoder, or one
    RenderError naming render.width (--resolution) and the fix, instead of "writing the video stopped" after the
    simulation."""
    from ..config import BUILTIN_SCENES
    from ..errors import RenderError
    from ..io.video import MAX_FRAME_SIDE as MAX_VIDEO_SIDE

    if cfg.scene not in BUILTIN_SCENES and cfg.capture.fit and cfg.capture.panel == "auto":
        return  # the capture's panel is chosen when it is prepared: 640 or 1280 pixels wide
    n, w = len(variants), cfg.render.width
    total = n * w + PANEL_GAP * (n - 1)
    if total > MAX_VIDEO_SIDE:
        widest = (MAX_VIDEO_SIDE - PANEL_GAP * (n - 1)) // n
        raise RenderError(
            f"render.width = {w} (--resolution) puts {n} variants side by side in a comparison video {total:,} "
            f"pixels wide, over the {MAX_VIDEO_SIDE:,} the H.264 encoder takes; use a width of at most {widest} "
            "pixels, or fewer variants."
        )


def frames_png_default(device: str) -> bool:
    """Whether a run on `device` writes frames/compare_NNNN.png unless told (`render-sim --frames-png`): on the CPU,
    where they cost about 5 ms a frame on the compose pool beside a solver that takes seconds a frame; not on CUDA,
    where the whole run takes a few seconds and the PNGs would be a tenth of it (docs/DESIGN.md, "Composing the
    comparison")."""
    return not str(device).startswith("cuda")


def clear_frames(out_dir: Path) -> None:
    """Remove frames/compare_NNNN.png an earlier run left in `out_dir` (and frames/, if that empties it), so a run
    that writes no PNGs leaves none that are not its own."""
    folder = out_dir / "frames"
    for png in folder.glob("compare_[0-9][0-9][0-9][0-9]*.png"):
        png.unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        folder.rmdir()  # only if empty


class ComparisonVideo:
    """comparison.mp4 and (`frames_png`) frames/compare_NNNN.png: the variants side by side at matched frames, with
    captions and, after the latch, circular insets around the latched interface projected into each
    panel. A variant that stopped early (diverged, interrupted) holds its last frame, captioned with
    why. Frames go out in order. `start_live` composes them on the pool, `LIVE_WINDOW` at a time, while
    variants still run (frame i once every running variant has rendered it);
    `finish` stops it after its current frame and composes the rest with a pool of threads (numpy,
    OpenCV and the PNG encoder release the GIL), at most two per thread ahead of the writer thread."""

    def __init__(
        self,
        cfg,
        variants,
        frame_lists,
        topology: Union[Topology, list, None],
        out_dir: Path,
        statuses,
        frames_png: bool = True,
    ):
        self.cfg, self.variants, self.frame_lists = cfg, list(variants), list(frame_lists)
        self.out_dir, self.statuses, self.frames_png = out_dir, list(statuses), frames_png
        # a history: the inset follows the first event's interface
        self.topology: Optional[Topology] = topology[0] if isinstance(topology, list) else topology
        if not frames_png:
            clear_frames(out_dir)
        self.video = FrameWriter(out_dir / "comparison.mp4", fps=cfg.render.fps)
        self._workers = max(1, min(8, os.cpu_count() or 1))
        self._pool = ThreadPoolExecutor(self._workers, thread_name_prefix="fgs-compose")
        self._pending: deque = deque()  # futures of submitted frames, oldest first
        self._submitted = 0
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._error: Optional[BaseException] = None

    def frame(self, i: int) -> np.ndarray:
        """Comparison frame i ([H, W, 3] uint8 on the host), also saved as frames/compare_NNNN.png (`frames_png`)."""
        cfg, topo = self.cfg, self.topology
        latch_frame = topo.latch_frame if topo is not None else None
        with phases.section("compose"):
            panels, insets, region = [], [], None
            if topo is not None and latch_frame is not None and i >= latch_frame:  # one camera for all panels of i
                region = compose.interface_region(topo.point, topo.normal, 0.04, frame_camera(cfg, i))
            for frames in self.frame_lists:
                img = frames[min(i, len(frames) - 1)]
                inset = None
                if region is not None and i < len(frames):
                    cx, cy, r = region
                    if 0 <= cx < img.shape[1] and 0 <= cy < img.shape[0]:
                        inset = Inset((cx, cy), float(np.clip(r, 8, cfg.render.inset_radius)), cfg.render.inset_zoom)
                on_device = getattr(img, "device_image", None)  # painter.DrawnFrame: the frame where it was drawn
                panels.append(on_device if on_device is not None else img)
                insets.append(inset)
            caps = [
                compose.caption_text(v, i * cfg.frame_dt, i)
                if i < len(f)
                else f"{compose.caption_text(v, (len(f) - 1) * cfg.frame_dt, len(f) - 1)}  {st.split(':')[0]}"
                for v, f, st in zip(self.variants, self.frame_lists, self.statuses)
            ]
            with _compose_stream(panels):
                frame = compose_row(panels, caps, insets)
        if self.frames_png:
            with phases.section("io"):
                save_png(self.out_dir / "frames" / f"compare_{i:04d}.png", frame)
        return frame

    def _pump(self, available: int, window: int) -> None:
        """Submit frames below `available` while fewer than `window` are pending, then hand the oldest to the writer."""
        while self._submitted < available and len(self._pending) < window:
            self._pending.append(self._pool.submit(self.frame, self._submitted))
            self._submitted += 1
        if self._pending:
            self.video.write(self._pending.popleft().result())  # to the writer thread

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
        """Stop composing and close the video as it is (the caller writes another, or raises what stopped the run:
        an error of the writer would only hide it)."""
        self._stop_live()
        self._pool.shutdown(wait=True, cancel_futures=True)
        with contextlib.suppress(Exception):
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
        except BaseException:
            self.abort()
            raise
        self._pool.shutdown(wait=True)
        self.video.close()  # waits for the writer thread; its error, if any, as one OutputError


def _compose_stream(panels):
    """On CUDA, the composer's own stream (the panels are complete: `DrawnFrame.of` waited for the render stream);
    elsewhere nothing. Pool threads must not use the legacy default stream beside variant threads' captures."""
    device = next((p.device for p in panels if torch.is_tensor(p)), None)
    if device is None or device.type != "cuda":
        return contextlib.nullcontext()
    return torch.cuda.stream(side_stream(device, "compose"))


def compose_comparison(
    cfg,
    variants,
    frame_lists,
    topology: Union[Topology, list, None],
    out_dir: Path,
    statuses=None,
    frames_png: bool = True,
):
    """The comparison video of finished variants (`ComparisonVideo`)."""
    statuses = statuses or ["ok"] * len(variants)
    ComparisonVideo(cfg, variants, frame_lists, topology, out_dir, statuses, frames_png).finish()
