"""`fracture-gs render-sim`: simulate each variant, render it, and write videos, metrics and a summary.

Outputs in DIR: <variant>.mp4, comparison.mp4 (side by side, captions, circular fracture insets),
frames/compare_NNNN.png (by default on the CPU only), metrics.jsonl, summary.json, summary.md, topology.npz,
config.toml, and view/ (the frames as `fracture-gs view` shows them).
Ctrl-C or a divergence keeps every frame and metric already written.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Literal, Optional

from tqdm import tqdm

from ..config import SceneConfig
from ..io.config import dump_config
from ..io.outputs import check_output_paths, output_dir
from ..io.video import ffmpeg
from ..pipeline import prepare_scene
from ..profiling import phases
from ..render.splat import check_backend
from ..render.warm_up import detached_notice, start_gsplat_compile
from ..runtime import import_in_background, usable_cores
from ..viewer.record import start_record
from .comparison import check_video_size, compose_comparison, frames_png_default
from .context import Export, RunContext, ScheduleResult
from .energy_report import energy_markdown
from .in_turn import run_in_turn
from .painter import Painter
from .summary import RunSummary, summary_markdown
from .variant import json_default

SCHEDULES = ("in_turn", "threads", "processes")
Schedule = Literal["auto", "in_turn", "threads", "processes"]
WORKER_START_WORK = 1_000_000
"""Particle-frames a worker process must simulate to pay for its start: a spawned one imports torch, Warp and the
package and loads the kernels (about 3 s on a 2-core CPU, while the solver simulates about 5 µs of host time per
particle-frame with its diagnostics and rendering). A forked one (`forked`, the CLI's) starts in milliseconds but
may fall back to spawning; below this a run stays in one process, which also keeps short runs and tests simple.
`auto` runs the variants in processes above it."""


def auto_schedule(device: str, variants: int, particles: int, frames: int, cores: int) -> Schedule:
    """How `schedule="auto"` shares one device: on the CPU, with more than one core and more than one variant,
    the variants run in worker processes (`processes`: Warp runs a kernel on one core, so one process simulates
    on one core) once each variant simulates long enough to pay for a worker's start (`WORKER_START_WORK`);
    else one after another (`in_turn`). A GPU's frames are host-bound and its variants share one card: in turn."""
    if device != "cpu" or variants < 2 or cores < 2 or particles * frames < WORKER_START_WORK:
        return "in_turn"
    return "processes"


def run_render_sim(
    cfg: SceneConfig,
    variants,
    device: str,
    out_dir,
    progress: bool = True,
    profile: bool = False,
    export_ply: Optional[int] = None,
    export_format: str = "ply",
    devices: Optional[list] = None,
    stop=None,
    schedule: Schedule = "in_turn",
    record_view: bool = True,
    frames_png: Optional[bool] = None,
) -> RunSummary:
    """The main job. Returns the run's summary (also written to summary.json / summary.md); with `profile`, the
    time per phase is in its `profile` and profile.md; with `export_ply` = N, every N-th frame of every variant
    also goes to ply/<variant>/frame_NNNN.<suffix> in `export_format` (ply, compressed-ply, splat or spz:
    `io.formats.write_gaussians`; the scene's frame).
    A captured scene is resolved first (`capture.resolve`): config.toml is the resolved config. With `devices`
    (several), the variants run side by side, one per device (`multi_device`). On one device `schedule` says
    how: "in_turn", one after the other (`in_turn`); "threads", at once, a thread each (`threads`: the same
    outputs, metrics.jsonl's rows interleaved); "processes", at once in worker processes, one per usable core
    at most (`multi_device` with the device repeated: the same outputs, byte for byte); "auto", processes on a
    CPU with cores to spare when the run is long enough to pay for their start (`auto_schedule`), else in turn.
    `stop`: a threading Event that interrupts the run at the next frame, like Ctrl-C (the CLI sets it from its
    SIGINT handler, so an interrupt Python drops inside a finalizer still stops the run; with `devices` the
    worker processes stop on Ctrl-C themselves and the event only marks the summary).
    `record_view`: also record every drawn frame for `fracture-gs view` in view/ (`viewer.record`, 18 bytes per
    Gaussian per frame and variant). `frames_png`: also write each comparison frame as frames/compare_NNNN.png
    (None: on the CPU only, `comparison.frames_png_default`)."""
    if schedule not in SCHEDULES + ("auto",):
        raise ValueError(f"schedule must be 'auto', 'in_turn', 'threads' or 'processes', got {schedule!r}")
    for d in devices if devices and len(devices) > 1 else [device]:
        check_backend(cfg.render.backend, d)  # now, not at the first frame
    check_video_size(cfg, variants)
    out_dir = output_dir(out_dir)
    check_output_paths(  # a folder where a file goes (or the reverse) fails now, not after the simulation
        out_dir,
        files=("comparison.mp4", *(f"{v}.mp4" for v in variants), "metrics.jsonl", "summary.json", "summary.md")
        + ("config.toml", "topology.npz", "profile.md"),
        folders=("frames",) * (frames_png is not False) + ("view",) * bool(record_view) + ("ply",) * bool(export_ply),
    )
    ffmpeg()  # a missing video encoder is one sentence now, not after the scene is prepared and simulated
    if profile:
        phases.enable(sync_device=device if device.startswith("cuda") else None)
    # worker processes are forked now, before the scene is prepared and before gsplat is looked for: later, with
    # torch's OpenMP threads started, a forked child could hang, and once gsplat's build was looked up (torch's
    # CUDA device query) a forked child cannot use CUDA (`forked`); a run that needs none ends them at once
    with _forked_workers(device, devices, schedule, len(variants), cfg.render.backend) as workers:
        if device.startswith("cuda") and any(v != "baseline" for v in variants):  # after any fork (`runtime`)
            import_in_background("scipy.ndimage", "scipy.spatial")  # a fracture event's components, the pieces' gap
        if cfg.render.backend != "torch" and not (devices and len(devices) > 1):  # (several devices: each builds)
            # gsplat's one-time CUDA build (about a minute and a half on a fresh machine) runs in a process of its
            # own beside the run, which draws with the torch rasterizer until it is done (`render.backend =
            # 'gsplat'` waits for it instead: `render.warm_up`). Nothing starts on the CPU or once it is built.
            position = len(variants) if schedule == "threads" else 1
            start_gsplat_compile(
                device, cancel=stop, show=progress, position=position, waits=cfg.render.backend == "gsplat"
            )
        with phases.section("setup"):
            scene = prepare_scene(cfg, device)
            cfg, gs = scene.cfg, scene.gaussians
            for note in scene.notes:
                tqdm.write(f"{cfg.name}: {note}")
            painter = Painter(gs, cfg, device, background=scene.background)
        if schedule == "auto":
            schedule = auto_schedule(device, len(variants), len(gs), cfg.frames, usable_cores())
        (out_dir / "config.toml").write_text(dump_config(cfg))
        ctx = RunContext(
            cfg=cfg,
            gaussians=gs,
            background=scene.background,
            device=device,
            out_dir=out_dir,
            variants=tuple(variants),
            order=tuple(sorted(variants, key=lambda v: v == "baseline")),  # a variant with a provider leads
            export=Export(int(export_ply), scene, export_format) if export_ply else None,
            view=start_record(out_dir, cfg, gs, scene.background, variants) if record_view else None,
            frames_png=frames_png_default(device) if frames_png is None else bool(frames_png),
        )
        with open(out_dir / "metrics.jsonl", "w") as metrics_file:
            result = _schedule(ctx, painter, metrics_file, devices, schedule, stop, workers)
    _finish_comparison(ctx, result)
    summary = RunSummary(
        name=cfg.name,
        scene=cfg.scene,
        preset=cfg.preset,
        device=device,
        particles=len(gs),
        capture=scene.notes,
        frames=cfg.frames,
        frame_dt=cfg.frame_dt,
        variants=[
            result.summaries[v].as_dict()
            if v in result.summaries
            else {"variant": v, "status": "not run (interrupted before it)", "interrupted": True}
            for v in ctx.variants
        ],
        interrupted=result.interrupted or (stop is not None and stop.is_set()),
        out_dir=str(out_dir),
    )
    _write_summary(summary, out_dir)
    notice = detached_notice()  # a fresh machine's gsplat build that outlived the run goes on for the next one
    if notice:
        tqdm.write(notice)
    if profile:
        from ..bytecode import profile_note  # the start-up cost that bytecode left out of cache would explain

        summary.profile = phases.report() + profile_note()
        (out_dir / "profile.md").write_text(f"# where the time went: {cfg.name} ({device})\n\n" + summary.profile)
        phases.disable()
    if summary.interrupted:
        raise KeyboardInterrupt(f"interrupted; partial outputs (frames, metrics, videos so far) are in {out_dir}")
    return summary


def cpu_slots(variants: int, cores: int, forked: bool) -> int:
    """Processes (this one included) that run the variants of one CPU run. Forked workers cost nothing to start,
    so each variant gets its own, up to two per core: the system shares the cores among them, and three equal
    variants on two cores all end at 1.5 variants' time instead of 2. A spawned worker imports torch and Warp
    anew (seconds of a core): one per core."""
    return max(1, min(variants, 2 * cores if forked else cores))


def forks_cuda_workers(device: str, devices, schedule: str) -> bool:
    """Whether a run may fork worker processes on a CUDA device (`_forked_workers`): one device, asked for by the
    processes schedule. Nothing may start CUDA in this process before the fork, so the CLI then checks the device
    through NVML and leaves Warp unstarted (`cli.devices`)."""
    return schedule == "processes" and str(device).startswith("cuda") and not (devices and len(devices) > 1)


@contextlib.contextmanager
def _forked_workers(device: str, devices, schedule: str, variants: int, backend: str = "auto"):
    """Worker processes forked now for a run that may take the processes schedule (`forked.ForkedWorkers`), or
    None; on the way out every one still running is stopped (the run failed, or was interrupted). A CPU run
    forks them for `auto` too; a GPU run only when asked (`schedule="processes"`) and while this process has not
    started the CUDA driver (`forked.cuda_untouched`): a forked child cannot use CUDA after its parent did.
    `backend` (`render.backend`): under `auto` a CUDA child loads gsplat's build while this process prepares the
    scene, or draws with the torch rasterizer where the build is missing (this process starts it after the fork);
    `gsplat`, which waits for the build, is given spawned workers instead (they wait for it themselves)."""
    cores = usable_cores()
    on_cuda = device.startswith("cuda")
    if on_cuda:
        asked = forks_cuda_workers(device, devices, schedule)
    else:
        asked = schedule in ("auto", "processes") and not (devices and len(devices) > 1)
    if not asked or variants < 2:
        yield None
        return
    from .forked import ForkedWorkers, can_fork, cuda_untouched

    if (cores < 2 and not on_cuda) or not can_fork() or (on_cuda and (backend == "gsplat" or not cuda_untouched())):
        yield None
        return
    workers = ForkedWorkers(cpu_slots(variants, cores, forked=True) - 1, device, gsplat=backend == "auto")
    try:
        yield workers
    finally:
        workers.terminate()


def _schedule(
    ctx: RunContext, painter: Painter, metrics_file, devices, schedule: str, stop, workers=None
) -> ScheduleResult:
    """The variants on several devices, in worker processes, in threads, or in turn. `workers`: processes forked
    at the run's start for the processes schedule; any other schedule ends them first."""
    if devices and len(devices) > 1:
        from .multi_device import run_on_devices

        return run_on_devices(ctx, list(devices), metrics_file)
    if schedule == "processes" and len(ctx.order) > 1:
        from .multi_device import run_on_devices

        slots = cpu_slots(len(ctx.order), usable_cores(), forked=workers is not None)
        return run_on_devices(ctx, [ctx.device] * slots, metrics_file, workers=workers)
    if workers is not None:
        workers.close()
    if schedule == "threads" and len(ctx.order) > 1:
        from .threads import run_in_threads

        return run_in_threads(ctx, painter, metrics_file, stop)
    return run_in_turn(ctx, painter, metrics_file, stop)


def _finish_comparison(ctx: RunContext, result: ScheduleResult) -> None:
    """comparison.mp4 of the variants that drew frames: the live one finished, or (a variant ended with no frame,
    or nothing was composed beside the run) one composed now."""
    done = [v for v in ctx.variants if v in result.summaries and result.frames[v]]
    statuses = [result.summaries[v].status for v in done]
    live = result.live
    if live is not None and done == live.variants:
        live.finish(statuses)
        return
    if live is not None:
        live.abort()
    if done:
        frames = [result.frames[v] for v in done]
        compose_comparison(ctx.cfg, done, frames, result.topology, ctx.out_dir, statuses, ctx.frames_png)


def _write_summary(summary: RunSummary, out_dir: Path) -> None:
    """summary.json and summary.md (a table per variant, then the energy account)."""
    (out_dir / "summary.json").write_text(json.dumps(summary.as_dict(), indent=2, default=json_default))
    (out_dir / "summary.md").write_text(
        f"# {summary.name}: {summary.scene} ({summary.preset}, {summary.particles} particles, {summary.device})\n\n"
        + summary_markdown(summary.variants)
        + energy_markdown(summary.variants)
    )
