"""Worker processes forked for a GPU run (`render-sim --schedule processes --device cuda:N`).

A child forked after its parent started the CUDA driver cannot use CUDA. So a GPU run that asks for processes checks
its device without starting the driver (torch's NVML check), leaves Warp unstarted until the workers are forked, forks
only while neither torch nor Warp has started CUDA, and each child proves CUDA works in it before the parent counts on
it: one that cannot says why at once, and the run spawns fresh workers instead. This machine has no GPU, which is the
case of a child whose CUDA does not work.
"""

from __future__ import annotations

import os
import queue
import time
from types import SimpleNamespace

import pytest

from fracture_gs.cli import devices, main
from fracture_gs.render_sim import forked, job


def _broken_cuda(jobs, ready, stop, results, device, gsplat, parent):  # a child whose CUDA does not work: says so
    fn, slot, threads, args, kwargs = jobs.get()
    ready.put((slot, f"CUDA does not work in a forked worker (on {device})"))


def _job(*args, stop, results):  # a job: says it ran
    results.put(("ran", args))


def test_a_child_without_cuda_is_given_up_at_once_with_its_reason(monkeypatch):
    """A child that reports CUDA broken makes `start` give up without waiting out READY_SECONDS: it returns None,
    keeps the child's reason for the run's message, and leaves no child running."""
    monkeypatch.setattr(forked, "_child", _broken_cuda)
    monkeypatch.setattr(forked, "READY_SECONDS", 60.0)
    workers = forked.ForkedWorkers(2, "cuda:0")
    t0 = time.perf_counter()
    assert workers.start(print, [(1, 1, (), {}), (2, 1, (), {})]) is None
    assert time.perf_counter() - t0 < 20
    assert workers.broken == "CUDA does not work in a forked worker (on cuda:0)"
    assert not any(p.is_alive() for p in workers.procs)


def test_the_real_child_proves_cuda_before_it_reports_ready(monkeypatch):
    """The package's own child, forked for a CUDA device that cannot work in it (cuda:99: no machine has it, and
    this one has no CUDA at all), reports that instead of ready, naming the error, and never runs its job."""
    monkeypatch.setattr(forked, "READY_SECONDS", 60.0)
    workers = forked.ForkedWorkers(1, "cuda:99")
    t0 = time.perf_counter()
    assert workers.start(_job, [(1, 1, ("cuda",), {})]) is None
    assert time.perf_counter() - t0 < 30
    assert workers.broken.startswith("CUDA does not work in a forked worker (")
    with pytest.raises(queue.Empty):  # the child returned before its job
        workers.results.get(timeout=0.5)


def test_the_cpu_child_does_not_touch_cuda():
    """A CPU run's child reports ready without trying CUDA (a CUDA-less machine's CPU run forks as before)."""
    workers = forked.ForkedWorkers(1, "cpu")
    procs = workers.start(_job, [(1, 1, ("cpu",), {})])
    assert procs is not None and workers.broken is None
    assert workers.results.get(timeout=30) == ("ran", ("cpu",))
    for p in procs:
        p.join(30)
    assert all(p.exitcode == 0 for p in procs)


@pytest.mark.parametrize(
    "device, schedule, untouched, backend, forks",
    [
        ("cuda:0", "processes", True, "auto", 2),  # asked for, CUDA unstarted: a worker per variant beyond this one
        ("cuda:0", "processes", True, "torch", 2),
        ("cuda:0", "processes", True, "gsplat", 0),  # waits for gsplat's build: spawned workers wait themselves
        ("cuda:0", "auto", True, "auto", 0),  # a GPU's auto runs in turn: nothing forked
        ("cuda:0", "in_turn", True, "auto", 0),
        ("cuda:0", "processes", False, "auto", 0),  # this process started CUDA already: its children could not use it
        ("cpu", "auto", True, "auto", 2),  # a CPU run forks for auto (two cores here)
        ("cpu", "processes", True, "torch", 2),
        ("cpu", "threads", True, "auto", 0),
    ],
)
def test_workers_are_forked_only_where_they_can_work(monkeypatch, device, schedule, untouched, backend, forks):
    """`_forked_workers`: a CPU run forks for auto and processes, a GPU run only for processes, only while this
    process has not started the CUDA driver, and not when it must wait for gsplat's build."""
    monkeypatch.setattr(forked, "cuda_untouched", lambda: untouched)
    monkeypatch.setattr(job, "usable_cores", lambda: 2)
    with job._forked_workers(device, None, schedule, 3, backend) as workers:
        got = 0 if workers is None else len(workers)
        if workers is not None:
            workers.close()
    assert got == forks


@pytest.mark.parametrize(
    "torch_started, warp_runtime, untouched",
    [
        (False, None, True),  # neither has started: fork
        (False, SimpleNamespace(cuda_devices=[]), True),  # Warp started on a machine without CUDA: fork
        (False, SimpleNamespace(cuda_devices=["cuda:0"]), False),  # Warp started the CUDA driver
        (True, None, False),  # torch did
    ],
)
def test_cuda_counts_as_touched_once_torch_or_warp_started_it(monkeypatch, torch_started, warp_runtime, untouched):
    """`cuda_untouched`: a fork is allowed only while neither torch's CUDA nor a Warp runtime with CUDA devices
    exists in this process."""
    from warp._src import context

    monkeypatch.setattr(forked.torch.cuda, "is_initialized", lambda: torch_started)
    monkeypatch.setattr(context, "runtime", warp_runtime)
    assert forked.cuda_untouched() is untouched


@pytest.mark.parametrize("before", [None, "0"])
def test_fork_safe_checks_ask_nvml_and_restore_the_environment(monkeypatch, before):
    """Inside `fork_safe_cuda_checks`, torch's availability check goes through NVML (which does not start the CUDA
    driver); outside, the variable is as it was, set or not."""
    if before is None:
        monkeypatch.delenv(devices.FORK_SAFE_CHECK, raising=False)
    else:
        monkeypatch.setenv(devices.FORK_SAFE_CHECK, before)
    with devices.fork_safe_cuda_checks():
        assert os.environ[devices.FORK_SAFE_CHECK] == "1"
    assert os.environ.get(devices.FORK_SAFE_CHECK) == before
    with devices.fork_safe_cuda_checks(False):
        assert os.environ.get(devices.FORK_SAFE_CHECK) == before


@pytest.mark.parametrize("schedule, fork_safe, init", [("processes", "1", False), ("in-turn", None, True)])
def test_a_gpu_processes_run_checks_its_device_and_leaves_warp_for_after_the_fork(
    monkeypatch, tmp_path, schedule, fork_safe, init
):
    """`render-sim --device cuda:0 --schedule processes`: the device is checked the fork-safe way and Warp is not
    started before the run (it starts at its first use, after the workers are forked); any other schedule checks
    and starts as before."""
    seen: dict = {}
    monkeypatch.delenv(devices.FORK_SAFE_CHECK, raising=False)

    def run_devices(args):
        seen["fork_safe"] = os.environ.get(devices.FORK_SAFE_CHECK)
        return "cuda:0", None

    def run(cfg, variants, device, out_dir, **kw):
        seen["run"] = (device, kw.get("schedule"))
        return SimpleNamespace(as_dict=lambda: {}, profile=None, variants=[])

    import fracture_gs.cli.run as cli_run
    import fracture_gs.render_sim as render_sim

    monkeypatch.setattr(cli_run, "run_devices", run_devices)
    monkeypatch.setattr(cli_run, "refuse_render_sim", lambda *a: None)
    monkeypatch.setattr(devices, "_prepare_warp", lambda init=True: seen.__setitem__("init", init))
    monkeypatch.setattr(render_sim, "run_render_sim", run)
    argv = ["render-sim", "bread", "--device", "cuda:0", "--schedule", schedule, "--out", str(tmp_path / "r")]
    assert main(argv) == 0
    assert seen == {"fork_safe": fork_safe, "init": init, "run": ("cuda:0", schedule.replace("-", "_"))}


class _Scalar:  # what `torch.ones(1, device=...).sum()` gives, without a GPU
    def sum(self):
        return self

    def item(self):
        return 1.0


@pytest.mark.parametrize("built, loads", [(True, True), (False, False)])
def test_a_cuda_child_loads_gsplat_at_the_fork_only_where_it_is_built(monkeypatch, built, loads):
    """`_start_cuda` under the auto backend: CUDA and Warp start; gsplat's CUDA code is imported only when its
    build exists (importing it unbuilt would start a minute-long compile in every child, or load a build the parent
    is still writing), and where it does not the child draws with the torch rasterizer (`gsplat_ready()` False)."""
    import builtins

    import fracture_gs.render.warm_up as warm_up
    import fracture_gs.runtime as runtime

    imported, started = [], []
    real_import = builtins.__import__

    def spy(name, *args, **kwargs):
        if name.startswith("gsplat"):
            imported.append(name)
            raise ImportError("no gsplat here")  # the child goes on without it: the first frame meets it again
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(forked.torch, "ones", lambda *a, **k: _Scalar())
    monkeypatch.setattr(runtime, "ensure_warp", lambda: started.append("warp"))
    monkeypatch.setattr(warm_up, "gsplat_needs_compile", lambda: not built)
    monkeypatch.setattr(warm_up, "_pending", None)
    assert warm_up.gsplat_ready()
    monkeypatch.setattr(builtins, "__import__", spy)
    assert forked._start_cuda("cuda:0", gsplat=True) is None
    monkeypatch.setattr(builtins, "__import__", real_import)
    assert started == ["warp"]
    assert (imported == ["gsplat.cuda"]) == loads and (imported == []) == (not loads)
    # unbuilt, the build is the parent's (started after the fork): this child draws with the torch rasterizer
    assert warm_up.gsplat_ready() is built
    from fracture_gs.render.splat import auto_backend

    assert auto_backend(on_cuda=True, warp_ok=False) == ("gsplat" if built else "torch")


def test_a_cuda_child_that_cannot_start_cuda_says_why_and_loads_nothing(monkeypatch):
    """A failing first CUDA op is the child's report, its first line quoted; Warp and gsplat are not touched."""
    import fracture_gs.runtime as runtime

    def no_cuda(*a, **k):
        raise RuntimeError("Cannot re-initialize CUDA in forked subprocess.\nmore detail")

    monkeypatch.setattr(forked.torch, "ones", no_cuda)
    monkeypatch.setattr(runtime, "ensure_warp", lambda: pytest.fail("Warp started without CUDA"))
    got = forked._start_cuda("cuda:0", gsplat=True)
    assert got == "CUDA does not work in a forked worker (Cannot re-initialize CUDA in forked subprocess.)"
