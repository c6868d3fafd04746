"""gsplat's one-time compile in the background (`render.warm_up`) and `fracture-gs info --warm-up` (`cli.warm_up`).

No GPU here: the background compile is driven with an injected compile function, and gsplat's rasterization with
a stand-in module, so what is tested is the contract a run relies on: the first render waits for the compile,
a failed compile is one RenderError at that render, Ctrl-C ends a wait, the compile is a step of the progress
display, and nothing starts where nothing needs building.
"""

from __future__ import annotations

import io
import sys
import threading
import time
import types

import pytest
import torch
from tqdm import tqdm

from fracture_gs import cli
from fracture_gs.errors import RenderError
from fracture_gs.render import splat, warm_up
from fracture_gs.render.camera import look_at
from fracture_gs.render.warm_up import BackgroundCompile, CompileStep, HeldEta, start_gsplat_compile


@pytest.fixture(autouse=True)
def no_pending(monkeypatch):
    """Each test starts with no background compile in the process (the registry is per process)."""
    monkeypatch.setattr(warm_up, "_pending", None)


def _gated(events: list):
    """A compile that runs until `release` is set, recording when it ends."""
    release = threading.Event()

    def compile():
        release.wait(10)
        events.append("compiled")

    return compile, release


def _until(predicate, seconds: float = 5.0) -> bool:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        if predicate():
            return True
        time.sleep(0.01)
    return False


def test_the_first_gsplat_render_waits_for_the_background_compile_then_draws(monkeypatch):
    """`splat._render_gsplat` (what every gsplat render goes through) must not call gsplat before the compile the
    run started has ended: with the compile held, a render on another thread (the render worker) stays blocked
    and gsplat is not called; once the compile ends the render proceeds and returns gsplat's image."""
    events: list = []
    compile, release = _gated(events)

    def rasterization(means, *args, **kwargs):
        events.append("rasterized")
        return torch.full((1, 4, 4, 3), 0.25), torch.ones(1, 4, 4, 1), {}

    monkeypatch.setitem(sys.modules, "gsplat", types.SimpleNamespace(rasterization=rasterization))
    job = start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=compile)
    assert job is not None and warm_up.pending_compile() is job
    camera = look_at((0.0, -3.0, 0.0), (0.0, 0.0, 0.0), width=4, height=4)
    means, covars = torch.zeros(2, 3), 1e-3 * torch.eye(3).expand(2, 3, 3)
    result: list = []
    render = threading.Thread(
        target=lambda: result.append(
            splat._render_gsplat(
                means, covars, torch.ones(2, 3), torch.ones(2), camera, torch.ones(3), "classic", 0.3, 0.01, 1e10
            )
        )
    )
    render.start()
    time.sleep(0.3)
    assert render.is_alive() and events == []  # waiting on the compile, gsplat untouched
    release.set()
    render.join(5)
    assert events == ["compiled", "rasterized"]
    img, alpha = result[0]
    assert img.shape == (4, 4, 3) and float(img[0, 0, 0]) == 0.25 and float(alpha.sum()) == 16.0
    assert warm_up.pending_compile() is None


def test_a_failed_compile_is_one_render_error_at_the_first_wait():
    """A compile that raised (a build's message holds the compiler's whole log) reaches the thread that renders
    as one RenderError: one line, one sentence naming the compile and the fixes, the original as its cause; a
    compile that failed with a RenderError of its own (no CUDA toolkit) keeps that sentence, not doubled."""
    log = "Error building extension 'gsplat_cuda':\n[1/12] nvcc -c rasterize.cu\nerror: bad thing\nninja: stopped"

    def broken():
        raise RuntimeError(log)

    start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=broken)
    with pytest.raises(RenderError) as caught:
        warm_up.wait_for_gsplat()
    message = str(caught.value)
    assert "\n" not in message and ". " not in message
    assert "gsplat CUDA compile (one time) failed (Error building extension 'gsplat_cuda')" in message
    assert "render.backend = 'torch'" in message and "info --warm-up" in message
    assert isinstance(caught.value.__cause__, RuntimeError)
    with pytest.raises(RenderError):  # every later render too: nothing to draw with
        warm_up.wait_for_gsplat()

    no_toolkit = RenderError("gsplat found no CUDA toolkit (nvcc) to build its CUDA code with; install it")
    job = BackgroundCompile("x", lambda: (_ for _ in ()).throw(no_toolkit)).start()
    with pytest.raises(RenderError) as caught:
        job.wait()
    assert str(caught.value) == str(no_toolkit)


def test_a_failed_compile_is_tried_again_by_the_next_run():
    """A run after a failed compile starts a new one (the toolkit may have been fixed), and a render then waits
    for the new one rather than raising the old failure."""
    start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=lambda: 1 / 0)
    assert _until(lambda: warm_up._pending.done)
    events: list = []
    again = start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=lambda: events.append(1))
    again.wait()
    warm_up.wait_for_gsplat()
    assert events == [1]


def test_ctrl_c_ends_a_wait_on_the_compile_at_once():
    """The run's stop event (Ctrl-C sets it) ends a render's wait within a fraction of a second although the
    compile goes on (a daemon thread: it never keeps the process alive)."""
    events: list = []
    compile, release = _gated(events)
    stop = threading.Event()
    job = start_gsplat_compile("cuda:0", cancel=stop, show=False, needs_compile=lambda: True, compile=compile)
    assert job._thread.daemon
    threading.Timer(0.2, stop.set).start()
    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        warm_up.wait_for_gsplat()
    assert time.perf_counter() - start < 1.0 and not job.done
    release.set()


def test_nothing_starts_where_nothing_needs_building():
    """No thread and no step on the CPU (gsplat is never built there, so it is not even asked) nor on CUDA with
    gsplat's build already there; a render then waits for nothing."""
    asked: list = []
    before = set(threading.enumerate())

    def needs():
        asked.append(1)
        return False

    def boom():
        raise AssertionError("must not compile")

    assert start_gsplat_compile("cpu", needs_compile=lambda: True, compile=boom) is None
    assert asked == []
    assert start_gsplat_compile("cuda:0", needs_compile=needs, compile=boom) is None
    assert asked == [1]
    assert warm_up.pending_compile() is None and warm_up._pending is None
    assert set(threading.enumerate()) <= before  # no thread started
    warm_up.wait_for_gsplat()


def test_the_compile_is_a_progress_step_of_its_own_that_ticks_and_closes():
    """On a terminal the compile has its own line, "gsplat CUDA compile (one time) … elapsed 00:00", redrawn while
    it runs; when it ends the line is cleared (the bar closed, no longer one of tqdm's) and one line says how long
    it took. In a log it is a line when it starts and one when it ends; a failure says so."""
    out = io.StringIO()
    step = CompileStep(warm_up.GSPLAT_STEP, file=out, position=1, bar=True)
    job = BackgroundCompile(warm_up.GSPLAT_STEP, lambda: time.sleep(0.4), step=step, tick=0.05).start()
    job.wait()
    assert _until(lambda: "done in" in out.getvalue())
    text = out.getvalue()
    assert text.count("gsplat CUDA compile (one time) … elapsed 00:00") >= 3  # redrawn while it ran
    assert "gsplat CUDA compile (one time): done in 0.4 s (cached for later runs)" in text
    assert step.bar.disable and step.bar not in tqdm._instances

    log = io.StringIO()
    step = CompileStep(warm_up.GSPLAT_STEP, file=log, bar=False)
    BackgroundCompile("x", lambda: 1 / 0, step=step, tick=0.05).start()
    assert _until(lambda: "failed after" in log.getvalue())
    lines = log.getvalue().splitlines()
    assert lines[0].startswith("gsplat CUDA compile (one time): started;")
    assert lines[1].startswith("gsplat CUDA compile (one time): failed after 0.") and "division by zero" in lines[1]


def test_a_frame_bar_shows_no_eta_while_the_compile_holds_it_and_leaves_the_wait_out_after():
    """While the compile runs a variant's bar shows no rate and no ETA (frames held up by a compile say nothing
    about the frames to come); once it is done, the bar's own ETA is back and the seconds its frames waited are
    left out of its elapsed time and rate (`held`)."""
    events: list = []
    compile, release = _gated(events)
    job = BackgroundCompile("x", compile).start()
    bar = tqdm(total=10, file=io.StringIO(), mininterval=0)
    eta = HeldEta(bar, job)
    bar.update(1)
    assert "ETA once gsplat's compile is done" in str(bar) and "<" not in str(bar)
    eta.check()  # still compiling: nothing changes
    time.sleep(0.4)  # the frames wait
    release.set()
    job.wait()
    eta.check()
    bar.update(1)
    assert eta.held >= 0.35
    assert bar.format_dict["elapsed"] < 0.2
    assert "ETA once" not in str(bar) and "<" in str(bar)
    bar.close()
    assert HeldEta(tqdm(total=3, file=io.StringIO())).compile is None  # no compile running: tqdm's own bar


def test_info_device_needs_warm_up_and_a_real_device(capsys):
    """`info --device` without --warm-up would do nothing, and a device that is no device is refused: each is one
    line and exit 2, before anything is printed or compiled."""
    assert cli.main(["info", "--device", "cpu"]) == 2
    err = capsys.readouterr().err
    assert "--device cpu only says where `info --warm-up` compiles" in err
    assert cli.main(["info", "--warm-up", "--device", "gpu"]) == 2
    captured = capsys.readouterr()
    assert "not a device" in captured.err and captured.out == ""


def test_the_warm_up_finds_every_kernel_module_of_the_simulator():
    """The modules the warm-up loads include every module of the package that defines kernels (the grid, boxes,
    physics, clock, linalg, diagnostics, differentiable kernels) and the fast-math grid updates that each build
    in a module of their own; a module missing here would compile on a run's first launch instead."""
    from fracture_gs.cli.warm_up import kernel_modules

    names = [m.name for m in kernel_modules()]
    for name in (
        "fracture_gs.linalg",
        "fracture_gs.sim.clock",
        "fracture_gs.sim.grid.kernels",
        "fracture_gs.sim.grid.run_kernels",
        "fracture_gs.sim.boxes.kernels",
        "fracture_gs.sim.physics.constitutive",
        "fracture_gs.sim.physics.boundary",
        "fracture_gs.sim.diagnostics.overlap_kernels",
        "fracture_gs.sim.diff.kernels",
    ):
        assert name in names, (name, names)
    assert sum(name.startswith("box_grid_update_fast") for name in names) == 4
    assert names == sorted(names) and len(set(names)) == len(names)


def test_a_module_loaded_again_says_already_loaded():
    """`load_modules` reports how each load came about from Warp's own load line: a module loaded from the cache
    or compiled says so, and loading it again in the same process (no load line) says "already loaded"."""
    import warp as wp

    from fracture_gs.cli.devices import _prepare_warp
    from fracture_gs.cli.warm_up import _LoadLines, load_modules
    from fracture_gs.linalg import polar_f32

    _prepare_warp()
    log, steps = _LoadLines(wp.get_logger()), []
    wp.set_logger(log)
    try:
        load_modules([polar_f32.module] * 2, "cpu", log, steps.append)
    finally:
        wp.set_logger(log.inner)
    assert steps[0].name == "module fracture_gs.linalg"
    assert steps[0].status in ("cached", "compiled", "already loaded")
    assert steps[1].status == "already loaded"


@pytest.mark.slow
def test_info_warm_up_on_the_cpu_loads_every_module_and_prints_each_step(capsys):
    """`fracture-gs info --warm-up --device cpu` in-process: the info rows, then a line per step with its time and
    how it went (Warp init, each kernel module cached, compiled or already loaded, one frame of bread, gsplat not
    needed on the CPU, the Python bytecode written or cached) and a summary; the frame of bread loads no module the
    list missed (0 more), so a run's launches find every module the warm-up put in the cache."""
    assert cli.main(["info", "--warm-up", "--device", "cpu"]) == 0
    out = capsys.readouterr().out
    assert "renderer" in out and "warm-up on cpu:" in out
    lines = out.splitlines()
    modules = [line for line in lines if line.startswith("  module ")]
    assert len(modules) >= 13
    for line in modules:
        assert line.rstrip().endswith(("cached", "compiled", "already loaded")), line
    assert any("module fracture_gs.sim.grid.kernels" in line for line in modules)
    frame = next(line for line in lines if "one frame of bread (300 particles)" in line)
    assert frame.rstrip().endswith("0 more module(s) loaded"), frame
    assert any("gsplat CUDA code" in line and "not needed on the CPU" in line for line in lines)
    bytecode = next(line for line in lines if "Python bytecode of the packages a run imports" in line)
    assert "cached" in bytecode or "module(s) compiled" in bytecode, bytecode
    assert f"{len(modules)} Warp kernel modules" in lines[-1] and "warm-up done in" in lines[-1]
