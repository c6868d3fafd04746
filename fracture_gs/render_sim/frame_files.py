"""A worker process's drawn frames, one file each, so the parent composes the comparison while the workers run.

In the CPU's processes schedule (`multi_device`) each variant draws in its own process. Before, a worker kept its
frames and saved them as one .npy when its variant ended, so the comparison video (compose, PNGs, encoding: about
2 s of the README's CPU job) could only start after the last variant, with the cores idle but one. Now the worker
writes each frame as it is drawn to DIR/frame_NNNNNN.npy (written to a temporary name and renamed, so a reader
never sees half a frame, the `FileChannel` contract) and the parent reads them as they appear: `FrameFiles` is
the list of frames on both sides, `append` in the worker, `len` and indexing in the parent's composer
(`comparison.ComparisonVideo.start_live`). The frames are the same arrays, so the comparison is byte for byte the
one composed after the run.
"""

from __future__ import annotations

import os
import shutil
import threading
from pathlib import Path

import numpy as np


class FrameFiles:
    """A variant's frames in folder `folder`: `append` writes one (the worker), `len` counts those written so far
    in order and `[i]` reads one (the parent, which keeps what it read)."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self._written = 0  # frames this process appended
        self._frames: list[np.ndarray] = []  # frames this process read, in order
        self._lock = threading.Lock()  # the composer's pool threads read at once

    def _path(self, i: int) -> Path:
        return self.folder / f"frame_{i:06d}.npy"

    def append(self, img) -> None:
        """Write frame `len` ([H, W, 3] uint8) under its final name at once."""
        tmp = self.folder / f".frame_{self._written:06d}.{os.getpid()}.tmp.npy"
        np.save(tmp, np.asarray(img))
        os.replace(tmp, self._path(self._written))
        self._written += 1

    def _read_new(self) -> None:
        with self._lock:
            while self._path(len(self._frames)).exists():
                self._frames.append(np.load(self._path(len(self._frames))))

    def __len__(self) -> int:
        if self._written:
            return self._written
        self._read_new()
        return len(self._frames)

    def __getitem__(self, i: int) -> np.ndarray:
        if not 0 <= i < len(self._frames):
            self._read_new()
        return self._frames[i]

    def __iter__(self):
        return iter([self[i] for i in range(len(self))])

    def remove(self) -> None:
        """Delete the folder; frames read so far stay readable."""
        shutil.rmtree(self.folder, ignore_errors=True)
