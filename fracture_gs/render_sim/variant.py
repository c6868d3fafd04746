"""One variant of a render-sim run: simulate it, draw each frame on a worker thread, encode its video.

`run_variant` runs the pipeline's frames (`pipeline.simulate`), writes each frame's metrics row to
metrics.jsonl as it comes, hands the frame to a `FrameSink` (render and encode beside the solver) and
returns the variant's `VariantSummary` and the topology history it latched. Ctrl-C, a stop event or a
divergence end the variant at a frame; everything before it is kept.
"""

from __future__ import annotations

import contextlib
import json
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Optional

import numpy as np
import torch
from tqdm import tqdm

from ..io.video import VideoWriter
from ..pipeline import FrameOutput, make_simulator, simulate
from ..profiling import phases
from ..render.warm_up import HeldEta
from ..runtime import current_lane, side_stream, stream_lane
from ..sim import SimulationDiverged
from ..sim.diagnostics.metrics import piece_gap
from ..viewer.record import FrameRecorder
from .context import Export, RunContext
from .painter import Painter
from .summary import VariantSummary, summarize


class FrameSink:
    """Renders, encodes and keeps the frames of one variant on a worker thread, so frame n is drawn
    while the solver runs frame n + 1 (Warp's and torch's kernels release the GIL). A bounded queue
    keeps at most two frames in flight; an error on the worker is raised in the caller at the next
    `put` or at `close`. Closing always drains what was queued (Ctrl-C and divergences keep every
    frame simulated so far). A `recorder` also gets each frame drawn, for the viewer."""

    def __init__(self, painter: Painter, video_path: Path, fps: int, store: list, recorder=None):
        self.painter, self.store = painter, store
        self.recorder: Optional[FrameRecorder] = recorder
        self.video = VideoWriter(video_path, fps=fps)
        self.error: Optional[BaseException] = None
        self.queue: queue.Queue = queue.Queue(maxsize=2)
        self.lane = current_lane()  # the producer's stream lane: variant threads draw on their own streams
        self.thread = threading.Thread(target=self._work, name="fgs-render", daemon=True)
        self.thread.start()

    def _work(self) -> None:
        with stream_lane(self.lane):
            self._drain()

    def _drain(self) -> None:
        while True:
            out = self.queue.get()
            if out is None:
                return
            if self.error is not None:
                continue
            try:
                with phases.section("render"), self._on_render_stream(out):
                    img = self.painter(out)
                    if self.recorder is not None:  # the colours and visibility just drawn, read on this stream
                        self.recorder.write(out, *self.painter.view_colors(out))
                with phases.section("encode"):
                    self.video.write(img)
                self.store.append(img)
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                self.error = exc

    @staticmethod
    def _on_render_stream(out: FrameOutput):
        """On CUDA, draw on the render stream once the producer's copies of the frame are done (the event
        `put` recorded), and keep those tensors' memory from reuse until the render stream is past them."""
        if out.ready is None:
            return contextlib.nullcontext()
        stream = side_stream(out.means.device, "render")
        stream.wait_event(out.ready)
        for t in (out.means, out.F, out.fragment, out.band):
            t.record_stream(stream)
        return torch.cuda.stream(stream)

    def put(self, out: FrameOutput) -> None:
        if self.error is not None:
            raise self.error
        if out.means.is_cuda:
            out.ready = torch.cuda.Event()
            out.ready.record(torch.cuda.current_stream(out.means.device))
        self.queue.put(out)

    def close(self) -> None:
        self.queue.put(None)
        self.thread.join()
        with phases.section("encode"):
            self.video.close()
        if self.recorder is not None:
            self.recorder.close()
        if self.error is not None:
            raise self.error


def run_variant(
    ctx: RunContext,
    variant: str,
    painter: Painter,
    metrics_file,
    frames_store: list,
    topology=None,
    provider=None,
    stop=None,
    position: int = 0,
) -> tuple[VariantSummary, Optional[list]]:
    """Simulate and draw one variant; its frames are appended to `frames_store` as they are drawn. Returns its
    summary and the topology history (the one replayed, or the one it latched). `topology`: a history to replay;
    `provider`: the event provider to use instead of the config's or the replay (variants side by side share a
    live one); `stop`: a threading or multiprocessing Event that interrupts the variant at its next frame (as
    Ctrl-C does); `position`: the progress bar's line."""
    cfg, gs = ctx.cfg, ctx.gaussians
    sim = make_simulator(cfg, gs, variant, ctx.device, topology=topology, provider=provider)
    rows, status, t0 = [], "ok", time.perf_counter()
    bar = progress_bar(cfg.frames, f"{variant:>20s}", position)
    # no ETA while gsplat's one-time build holds the frames up (render.backend = 'gsplat'), its wait left out after
    eta = HeldEta(bar, waits=cfg.render.backend == "gsplat", first_frame=True)  # and none from the first frame alone
    recorder = FrameRecorder(ctx.view, variant) if ctx.view is not None else None
    sink = FrameSink(painter.for_variant(), ctx.out_dir / f"{variant}.mp4", cfg.render.fps, frames_store, recorder)
    interrupted = False
    try:
        for out in simulate(
            sim,
            painter.cov0,
            cfg.frames,
            cfg.frame_dt,
            carrier=gs.carrier,
            crack_faces=cfg.render.trim_cracks,
            max_stretch=cfg.render.max_stretch,
        ):
            with phases.section("io"):
                metrics_file.write(json.dumps({"variant": variant, **out.metrics}, default=json_default) + "\n")
                metrics_file.flush()
            rows.append(out.metrics)
            if stop is not None and stop.is_set():
                raise KeyboardInterrupt
            if ctx.export is not None and out.frame % ctx.export.every == 0:
                with phases.section("io"):
                    _export(out, painter, ctx.export, ctx.out_dir / "ply" / variant, f"frame_{out.frame:04d}")
            sink.put(out)
            if out.frame > 0:
                eta.check()
                elapsed = time.perf_counter() - t0 - eta.held
                bar.set_postfix(
                    substeps_per_s=f"{sim.substeps / elapsed:.0f}",
                    fragments=sim.n_fragments,
                    overflow=sim.slot_overflow_total,
                    refresh=False,
                )
                bar.update(1)
    except SimulationDiverged as err:
        status = f"diverged at frame {err.frame}: {err.cause}"
        tqdm.write(f"{variant}: {err}")
        metrics_file.write(json.dumps({"variant": variant, "frame": err.frame, "diverged": str(err)}) + "\n")
    except KeyboardInterrupt:
        interrupted = True
        status = f"interrupted at frame {rows[-1]['frame'] if rows else 0}"
    finally:
        bar.close()
        sink.close()
    if sim.topologies and topology is None:
        topology = list(sim.topologies)
    summary = summarize(variant, rows, status, time.perf_counter() - t0)
    summary.piece_gap = piece_gap(sim.particles.x, sim.particles.fragment, sim.grid.dx)
    summary.interrupted = interrupted
    return summary, topology


def _export(out: FrameOutput, painter: Painter, export: Export, folder: Path, stem: str) -> None:
    """One frame to folder/stem + the format's suffix, in the scene's own coordinates."""
    from ..capture.export import export_ply, frame_gaussians
    from ..io.formats import SUFFIX

    cap = export.capture
    drawn = ~painter.interior | painter._exposed(out)
    gs = frame_gaussians(cap.gaussians, out.means, out.covars, out.rotations, drawn)
    to_scene = cap.transform.inverse() if cap.transform is not None else None
    export_ply(folder / f"{stem}{SUFFIX[export.format]}", gs, cap.background, to_scene, export.format)


def progress_bar(total: int, desc: str, position: int = 0) -> tqdm:
    """A tqdm bar; in a non-interactive log (stderr not a terminal) it prints a line every few
    seconds instead of every update."""
    interactive = sys.stderr.isatty()
    return tqdm(
        total=total,
        desc=desc,
        position=position,
        unit="frame",
        leave=True,
        dynamic_ncols=True,
        mininterval=0.1 if interactive else 5.0,
        maxinterval=10.0 if interactive else 30.0,
    )


def json_default(o):
    """JSON for tensors and numpy scalars (metrics rows and summaries)."""
    if torch.is_tensor(o):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o))
