"""A video written by a thread of its own (`FrameWriter`): whoever makes the frames hands them over and goes on.

The comparison video's frames are composed beside the solver; handing each to ffmpeg (a pipe write that blocks
while the encoder is behind) and closing the video (ffmpeg flushes its look-ahead, tenths of a second) are the
writer thread's, so the composer waits only when `depth` frames are queued. The variants' own videos are encoded
on their render worker already (`variant.FrameSink`), which is itself beside the solver.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path
from typing import Optional

from ..errors import OutputError
from ..io.video import VideoWriter
from ..profiling import phases

_END = object()


class FrameWriter:
    """An H.264 video (`io.video.VideoWriter`) written on a thread: `write` queues a frame (waiting only while
    `depth` frames are queued) and returns; the thread writes them in order. `close` waits for the thread, closes
    the video and raises what went wrong on the thread as one OutputError. After an error the thread keeps taking
    frames off the queue and drops them, so a producer never waits for a writer that stopped."""

    def __init__(self, path, fps: float, depth: int = 8, video=None):
        self.path = Path(path)
        self.video = video if video is not None else VideoWriter(self.path, fps=fps)
        self.written = 0
        self.error: Optional[BaseException] = None
        self._queue: queue.Queue = queue.Queue(maxsize=depth)
        self._closed = False
        self._thread = threading.Thread(target=self._work, name="fgs-writer", daemon=True)
        self._thread.start()

    def _work(self) -> None:
        while True:
            frame = self._queue.get()
            if frame is _END:
                break
            if self.error is not None:
                continue
            try:
                with phases.section("encode"):
                    self.video.write(frame)
                self.written += 1
            except BaseException as exc:  # noqa: BLE001 - raised by close()
                self.error = exc
        try:
            with phases.section("encode"):
                self.video.close()
        except BaseException as exc:  # noqa: BLE001 - raised by close()
            self.error = self.error or exc

    def write(self, frame) -> None:
        """Queue one frame ([H, W, 3] uint8) for the video."""
        if self._closed:
            raise ValueError(f"{self.path}: the writer is closed; write every frame before close()")
        self._queue.put(frame)

    def close(self) -> None:
        """Write what is queued, close the video, and raise the thread's error, if any, as an OutputError."""
        if not self._closed:
            self._closed = True
            self._queue.put(_END)
        self._thread.join()
        err = self.error
        if err is None:
            return
        if isinstance(err, OutputError):
            raise err
        raise OutputError(
            f"{self.path}: writing the video stopped after {self.written} frames ({type(err).__name__}: {err}); "
            "check that the disk has space and the folder is writable, then run again"
        ) from err
