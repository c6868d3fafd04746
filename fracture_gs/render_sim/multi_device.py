"""`render-sim --devices cuda:0,cuda:1,...`: the variants of one comparison side by side on several
devices of one machine: the first device's in this process, each other device's in a worker process.

Processes, not threads: a variant's frame is much Python (diagnostics issue many small torch ops, the
frame loop, rendering and encoding), so two threads in one interpreter took as long on two GPUs as on
one (the bread paper preset; BENCHMARKS.md, "Beyond one GPU"); each process has its own interpreter. A
worker process pays its start (torch, Warp, gsplat, the kernels: seconds), so the first device's
variants run in the caller at once and a second device pays off when a variant simulates for longer
than that.

The same scheduler shares one CPU among its cores (`render-sim --schedule processes`, `auto`'s choice for
long CPU runs): the device repeated, one worker process per usable core. Warp runs each kernel on one
core, so one process simulates on one core however many it has; two processes simulate on two.

The first variant that runs an event provider leads, on the first device. What it latches is handed
to the others as it happens through a folder of per-frame files (`FileChannel`: written atomically,
polled by the followers), so every variant uses the one topology the leader found — the contract of
the sequential run, where the others replay the leader's saved history. Variants beyond the number of
devices queue on them in order. Each worker writes its variant's video and metrics; its frames come
back to the parent (for comparison.mp4) as one .npy per variant, or, on one CPU, one file per frame as it is
drawn (`frame_files`), so the parent, once its own variants are done, composes the comparison while the workers
finish. Ctrl-C or an error in one worker stops the others at their next frame; an
error is raised here with the worker's traceback.
"""

from __future__ import annotations

import queue
import shutil
import threading
import traceback
from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np
import torch
from tqdm import tqdm

from ..profiling import phases
from ..runtime import share_cpu, usable_cores
from ..sim.providers import make_provider
from ..sim.providers.broadcast import BroadcastProvider, FileChannel, LeaderProvider
from ..sim.topology import save_history
from .comparison import ComparisonVideo
from .context import RunContext, ScheduleResult
from .forked import ForkedWorkers
from .frame_files import FrameFiles
from .painter import Painter
from .variant import run_variant


@dataclass(frozen=True)
class WorkerSetup:
    """How every worker of one run is set up, as the parent is: `threads` torch threads (the CPU reductions then
    sum in the same order), `run` the variant runner, `profile` whether a spawned worker times its phases (sent
    back last, the parent adds them up), `cores` its share of a CPU that several workers split
    (`runtime.share_cpu`), or None."""

    threads: int
    run: Callable
    profile: bool = False
    cores: Optional[int] = None


def _worker(
    slot: int,
    ctx: RunContext,
    variants,
    leader,
    channel_dir,
    stop,
    results,
    setup: WorkerSetup,
    frame_dir=None,
    stores=None,
) -> None:
    """One device's variants (`ctx.device`), in order (in a spawned process, or in the caller for the first
    device: then `results` is a plain queue.Queue and the frames travel in the message instead of a .npy file).
    `frame_dir`: a worker process writes each frame to frame_dir/<variant>/ as it is drawn (`FrameFiles`) instead
    of one .npy at the end. `stores`: the caller's lists to draw its variants' frames into (variant → list)."""
    local = isinstance(results, queue.Queue)
    run, profile, cores = setup.run, setup.profile, setup.cores
    torch.set_num_threads(setup.threads)
    before = share_cpu(cores) if cores is not None else None
    if profile and not local:
        phases.enable()
    cfg, device, out_dir = ctx.cfg, ctx.device, ctx.out_dir
    try:
        if device.startswith("cuda"):
            torch.cuda.set_device(torch.device(device))
        ctx = replace(ctx, gaussians=ctx.gaussians.to(device))
        painter = Painter(ctx.gaussians, cfg, device, background=ctx.background)
        channel = FileChannel(channel_dir)
        for variant in variants:
            if stop.is_set():
                break
            provider = (
                LeaderProvider(make_provider(cfg.topology), channel)
                if variant == leader
                else BroadcastProvider(channel)
            )
            if local:
                frames = stores[variant] if stores is not None else []
            else:
                frames = FrameFiles(frame_dir / variant) if frame_dir is not None else []
            metrics = out_dir / f".metrics_{variant}.jsonl"
            try:
                with open(metrics, "w") as fh:
                    summary, history = run(
                        ctx, variant, painter, fh, frames, provider=provider, stop=stop, position=slot
                    )
            finally:
                if variant == leader:
                    channel.close()  # followers past the leader's last frame stop waiting
            if not local and frame_dir is None:
                stacked = np.stack(frames) if frames else np.zeros((0, 1, 1, 3), np.uint8)
                np.save(out_dir / f".frames_{variant}.npy", stacked)
            if variant == leader:  # through a file: tensors in a queue need their sender alive to be read
                torch.save([replace(t, fragment=t.fragment.cpu(), band=t.band.cpu()) for t in history or []],
                           out_dir / ".leader_history.pt")  # fmt: skip
            results.put(("done", variant, summary, frames if local else None))
            if summary.interrupted:
                stop.set()
    except KeyboardInterrupt:
        stop.set()
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        stop.set()
        results.put(("error", device, f"{type(exc).__name__}: {exc}", traceback.format_exc()))
    finally:
        if profile and not local:
            results.put(("phases", device, dict(phases.seconds), dict(phases.calls)))
        if cores is not None:
            share_cpu(before)


class WorkerFailed(RuntimeError):
    """A worker process of `render-sim --devices` failed; the message carries its error and traceback."""


def run_on_devices(
    ctx: RunContext, devices: list[str], metrics, run=run_variant, workers: Optional[ForkedWorkers] = None
) -> ScheduleResult:
    """Run `ctx.order` (leader first) over `devices` (one worker process per entry; an entry may repeat); the
    variants' metrics lines are appended to `metrics` in that order, and the leader's history to topology.npz.
    `run` runs one variant (`variant.run_variant`; a test passes a stand-in defined at module level, which the
    spawned workers import). `workers`: processes forked at the run's start (`forked.ForkedWorkers`, the CPU's
    processes schedule), used instead of spawning new ones."""
    order, out_dir = list(ctx.order), ctx.out_dir
    channel_dir = out_dir / ".topology_channel"
    shutil.rmtree(channel_dir, ignore_errors=True)
    queues: list[list[str]] = [[] for _ in devices]
    for i, v in enumerate(order):
        queues[i % len(devices)].append(v)
    bg = ctx.background
    on_cpu = replace(ctx, gaussians=ctx.gaussians.to("cpu"), background=bg.to("cpu") if bg is not None else None)
    one_cpu = all(d == "cpu" for d in devices)
    # workers sharing one CPU split its cores: each kernel's ranges stay on its own share (bitwise the same)
    cores = max(1, usable_cores() // len(devices)) if one_cpu else None
    setup = WorkerSetup(torch.get_num_threads(), run, phases.enabled, cores)
    # one device shared by processes: the workers' frames come file by file (`FrameFiles`), so this process composes
    # the comparison while they finish; several devices: one .npy per variant at its end
    frame_dir = out_dir / ".frames" if len(set(devices)) == 1 else None
    if frame_dir is not None:
        shutil.rmtree(frame_dir, ignore_errors=True)
    jobs = [  # `_worker`'s leading arguments: the first device's variants run here, the others' in worker processes
        (i, replace(on_cpu, device=devices[i]), vs, order[0], channel_dir)
        for i, vs in enumerate(queues)
        if vs and i > 0
    ]
    procs = None
    if workers is not None:
        procs = workers.start(
            _worker, [(job[0], setup.threads, job, {"setup": setup, "frame_dir": frame_dir}) for job in jobs]
        )
    if workers is not None and procs is not None:
        stop, results = workers.stop, workers.results
        tqdm.write(f"render-sim: {len(order)} variants in {len(procs) + 1} processes (forked at the start)")
    else:
        if workers is not None:
            tqdm.write(f"render-sim: {workers.broken}; spawning fresh workers, which import torch and Warp again")
        mp = torch.multiprocessing.get_context("spawn")
        stop, results = mp.Event(), mp.Queue()
        procs = [
            mp.Process(
                target=_worker,
                args=job,
                kwargs={"stop": stop, "results": results, "setup": setup, "frame_dir": frame_dir},
                name=f"fgs-{job[1].device}-{job[0]}",
                daemon=True,
            )
            for job in jobs
        ]
        for p in procs:
            p.start()
    local: queue.Queue = queue.Queue()
    stores: dict[str, list] = {v: [] for v in queues[0]}  # this process's variants draw into these
    readers = {v: FrameFiles(frame_dir / v) for v in order if v not in stores} if frame_dir is not None else {}
    live = None
    interrupted = False
    try:
        _worker(0, replace(ctx, device=devices[0]), queues[0], order[0], channel_dir, stop, local, setup, stores=stores)
        if readers:  # this process led; while the workers finish, compose what they have drawn
            live = _LiveComparison(ctx, channel_dir, [stores.get(v, readers.get(v)) for v in ctx.variants])
    except KeyboardInterrupt:
        interrupted = True
        stop.set()
    messages = list(local.queue)
    while True:
        try:
            alive = any(p.is_alive() for p in procs)
            try:
                messages.append(results.get(timeout=0.2))
            except queue.Empty:
                if not alive:
                    break
        except KeyboardInterrupt:  # the workers got it too: they stop at their next frame and report
            interrupted = True
            stop.set()
    summaries = {m[1]: m[2] for m in messages if m[0] == "done"}
    for m in messages:
        if m[0] == "phases":
            phases.merge(m[2], m[3])
    errors = [m for m in messages if m[0] == "error"]
    for p in procs:
        p.join()
    video = live.stop() if live is not None else None
    frames = {m[1]: m[3] for m in messages if m[0] == "done" and m[3] is not None}
    for v in order:
        path = out_dir / f".frames_{v}.npy"
        if v not in frames:
            frames[v] = list(readers[v]) if v in readers else list(np.load(path)) if path.exists() else []
        path.unlink(missing_ok=True)
        part = out_dir / f".metrics_{v}.jsonl"
        if part.exists():
            metrics.write(part.read_text())
            part.unlink()
    metrics.flush()
    shutil.rmtree(channel_dir, ignore_errors=True)
    if frame_dir is not None:
        shutil.rmtree(frame_dir, ignore_errors=True)  # every frame was read above
    saved = out_dir / ".leader_history.pt"
    history = (torch.load(saved, weights_only=False) or None) if saved.exists() else None  # [] = nothing latched
    saved.unlink(missing_ok=True)
    crashed = [p for p in procs if p.exitcode not in (0, None)] if not interrupted else []
    if (errors or crashed) and video is not None:
        video.abort()  # the run fails: what the workers drew is not a comparison to finish
    if errors:
        _, device, message, trace = errors[0]
        raise WorkerFailed(f"the worker on {device} failed: {message}\n{trace}")
    if crashed:
        raise WorkerFailed(f"worker process {crashed[0].name} exited with code {crashed[0].exitcode} before reporting")
    interrupted = interrupted or any(s.interrupted for s in summaries.values())
    if history is not None:
        save_history(out_dir / "topology.npz", history)
    return ScheduleResult(frames, summaries, history, interrupted, video)


class _LiveComparison:
    """The comparison video composed in this process while the workers still run (`ComparisonVideo.start_live`),
    once the leader has latched (the insets need its interface: read from the topology channel): `panels` are the
    variants' frame lists in the video's order, this process's own lists and the workers' `FrameFiles`. Started
    when this process's own variants are done: this process runs the leader, which every follower waits for frame
    by frame, so composing beside it would slow them all (the composer's threads share its interpreter lock)."""

    def __init__(self, ctx: RunContext, channel_dir, panels: list):
        self.ctx, self.panels = ctx, panels
        self.video: Optional[ComparisonVideo] = None
        self.channel = FileChannel(channel_dir)
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._wait_for_latch, name="fgs-live-compare", daemon=True)
        self.thread.start()

    def _wait_for_latch(self) -> None:
        while not self.done.wait(0.05):
            first = self.channel.first()
            if first is not None:
                ctx = self.ctx
                statuses = ["ok"] * len(self.panels)
                video = ComparisonVideo(
                    ctx.cfg, ctx.variants, self.panels, first, ctx.out_dir, statuses, ctx.frames_png
                )
                video.start_live(*self.panels)
                self.video = video
                return

    def stop(self) -> Optional[ComparisonVideo]:
        """Stop waiting; the video if it started (the job finishes it with the variants' statuses), else None."""
        self.done.set()
        self.thread.join()
        return self.video
