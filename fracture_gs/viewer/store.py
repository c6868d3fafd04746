"""Reading a run's view record (`RUN_DIR/view/`, layout in `format`) frame by frame, on demand.

`open_run` checks the folder once and says in one sentence why it cannot be shown (no such folder, not a run,
a run written before the viewer existed or by a newer version, a damaged header, no frame drawn yet); a run cut
short opens with the frames it has, and `RunView.notes` says what is missing. A frame's bytes are read only when
it is asked for (`RunView.frame`), so a run of any length opens at once and memory holds what is shown.
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ViewError
from . import format as fmt
from .record import FOLDER


@dataclass
class Frame:
    """One variant's frame as recorded: centres, covariances and the epoch's colours, flags and fragment ids."""

    frame: int
    time: float
    means: np.ndarray  # [N,3] float32 [m]
    cov: np.ndarray  # [N,6] float16 upper triangle, in units of the run's cov_unit [m²]
    rgb: np.ndarray  # [N,3] uint8
    flags: np.ndarray  # [N] uint8 format.DRAWN | BAND | INTERFACE | INTERIOR
    fragment: np.ndarray  # [N] int16, −1 before the first fracture
    box: tuple[np.ndarray, np.ndarray]  # the frame's bounding box (lo, hi) [m]


class RunView:
    """A run's view record opened for reading (`open_run`); thread-safe."""

    def __init__(self, run_dir: Path, header: dict, static: dict, counts: dict[str, int], notes: list[str]):
        self.run_dir, self.folder = run_dir, run_dir / FOLDER
        self.header, self.static = header, static
        self.n = int(header["gaussians"])
        self.counts = counts
        """Frames viewable per variant (variants with none left out)."""
        self.variants = [v for v in header["variants"] if counts.get(v, 0) > 0]
        self.notes = notes
        """One line per thing missing (a variant cut short or never run)."""
        self._epochs: OrderedDict = OrderedDict()  # (variant, epoch) -> decoded epoch, a few kept
        self._lock = threading.Lock()

    @property
    def frames(self) -> int:
        """Frames on the slider: the longest variant's (a shorter one shows its last frame after it ends)."""
        return max(self.counts.values())

    def _read(self, path: Path, offset: int, size: int) -> bytes:
        with open(path, "rb") as f:
            f.seek(offset)
            return f.read(size)

    def _epoch(self, variant: str, epoch: int) -> dict:
        key = (variant, epoch)
        with self._lock:
            if key in self._epochs:
                self._epochs.move_to_end(key)
                return self._epochs[key]
        size = fmt.epoch_bytes(self.n)
        data = fmt.decode_epoch(self._read(self.folder / f"{variant}{fmt.EPOCHS_SUFFIX}", epoch * size, size), self.n)
        with self._lock:
            self._epochs[key] = data
            while len(self._epochs) > 4:
                self._epochs.popitem(last=False)
        return data

    def frame(self, variant: str, k: int) -> Frame:
        """Frame k of `variant` (clamped to the frames it has), read from disk now."""
        if variant not in self.counts:
            raise ViewError(f"variant {variant!r} has no frames in {self.run_dir}; choose one of {self.variants}.")
        k = min(max(int(k), 0), self.counts[variant] - 1)
        size = fmt.frame_bytes(self.n)
        rec = fmt.decode_frame(self._read(self.folder / f"{variant}{fmt.FRAMES_SUFFIX}", k * size, size), self.n)
        ep = self._epoch(variant, rec["epoch"])
        return Frame(
            rec["frame"], rec["time"], rec["means"], rec["cov"], ep["rgb"], ep["flags"], ep["fragment"], rec["box"]
        )


def _count(folder: Path, variant: str, n: int) -> int:
    """Whole frame records of `variant` whose header and epoch are both on disk (a cut-short run's last partial
    record, or a frame whose epoch record was cut, is left out)."""
    frames, epochs = folder / f"{variant}{fmt.FRAMES_SUFFIX}", folder / f"{variant}{fmt.EPOCHS_SUFFIX}"
    if not frames.exists() or not epochs.exists():
        return 0
    size, esize = fmt.frame_bytes(n), fmt.epoch_bytes(n)
    whole_epochs = epochs.stat().st_size // esize
    count = 0
    with open(frames, "rb") as f:
        for k in range(frames.stat().st_size // size):
            f.seek(k * size)
            head = f.read(fmt.FRAME_HEADER)
            if head[:4] != fmt.FRAME_MAGIC or not 0 <= int(np.frombuffer(head, "<i4", 1, 8)[0]) < whole_epochs:
                break
            count += 1
    return count


def _fix(run_dir: Path) -> str:
    return f"rerun `fracture-gs render-sim CONFIG --out {run_dir}` with this version to record it"


def open_run(run_dir) -> RunView:
    """Open RUN_DIR's view record, or raise ViewError with one sentence saying why it cannot be shown."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ViewError(f"{run_dir}: no such folder; pass the --out folder of a `fracture-gs render-sim` run.")
    folder = run_dir / FOLDER
    index = folder / fmt.INDEX
    if not index.is_file():
        if (run_dir / "summary.json").exists() or (run_dir / "metrics.jsonl").exists():
            raise ViewError(
                f"{run_dir} has no viewable frames: it was written by a fracture-gs without the viewer's record "
                f"(no {FOLDER}/{fmt.INDEX}); {_fix(run_dir)}."
            )
        raise ViewError(
            f"{run_dir} has no viewable frames: it is not a render-sim output folder (no {FOLDER}/{fmt.INDEX}); "
            "pass the --out folder of a `fracture-gs render-sim` run."
        )
    try:
        header = json.loads(index.read_text())
        if not isinstance(header, dict):
            raise ValueError("not a JSON object")
    except (ValueError, UnicodeDecodeError) as exc:
        raise ViewError(f"{index} is damaged ({exc}); {_fix(run_dir)}.") from None
    if header.get("format") != fmt.FORMAT:
        raise ViewError(f"{index} is not a fracture-gs view record (format {header.get('format')!r}); {_fix(run_dir)}.")
    version = header.get("version")
    if version != fmt.VERSION:
        newer = isinstance(version, int) and version > fmt.VERSION
        raise ViewError(
            f"{run_dir} was written by {header.get('writer', 'another fracture-gs')} (view format {version}, this "
            f"fracture-gs reads {fmt.VERSION}); "
            + ("upgrade fracture-gs to view it." if newer else f"{_fix(run_dir)}.")
        )
    try:
        n = int(header["gaussians"])
        variants = [str(v) for v in header["variants"]]
        float(header["cov_unit"]), dict(header["camera"])
        with np.load(folder / fmt.STATIC) as z:
            static = {k: z[k] for k in z.files}
        if len(static["opacity"]) != n:
            raise ValueError(f"{fmt.STATIC} holds {len(static['opacity'])} Gaussians, the header {n}")
    except (KeyError, TypeError, ValueError, OSError) as exc:
        raise ViewError(f"{folder} is damaged ({exc}); {_fix(run_dir)}.") from None
    counts = {v: _count(folder, v, n) for v in variants}
    if not any(counts.values()):
        raise ViewError(
            f"{run_dir} has no viewable frames: the run stopped before its first frame was drawn; {_fix(run_dir)}."
        )
    planned = int(header.get("frames", 0)) + 1  # frames 0 … frames
    notes = []
    for v in variants:
        if counts[v] == 0:
            notes.append(f"{v}: no frames (not run: the run was cut short before it)")
        elif counts[v] < planned:
            notes.append(f"{v}: {counts[v]} of {planned} frames (the run was cut short or the variant diverged)")
    return RunView(run_dir, header, static, {v: c for v, c in counts.items() if c}, notes)


def describe(view: RunView) -> str:
    """One line for the terminal: what the viewer shows."""
    h = view.header
    parts = [f"{v} ({view.counts[v]} frames)" for v in view.variants]
    text = f"{h.get('name', '?')}: {view.n:,} Gaussians, " + ", ".join(parts)
    if h.get("background"):
        text += f", {int(h['background']):,} static background Gaussians"
    return text
