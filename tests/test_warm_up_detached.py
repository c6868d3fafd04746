"""gsplat's one-time build in a process of its own, and the torch rasterizer drawing meanwhile (`render.warm_up`).

On a fresh GPU machine the build takes about a minute and a half, longer than a warm run of the main job. A run
therefore draws its CUDA frames with the torch rasterizer until gsplat is loaded, and the build runs detached
(its own session) so that it outlives a short run and is cached for the next. No GPU here: the build is a
stand-in command, and the backend choice is `splat.auto_backend`, the rule `render` applies for `auto`.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from fracture_gs.errors import RenderError
from fracture_gs.render import splat, warm_up
from fracture_gs.render.warm_up import BackgroundCompile, build_gsplat_detached, start_gsplat_compile

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def no_pending(monkeypatch):
    """Each test starts with no background compile in the process (the registry is per process)."""
    monkeypatch.setattr(warm_up, "_pending", None)


def _until(predicate, seconds: float = 10.0) -> bool:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_auto_draws_cuda_frames_with_torch_while_gsplat_builds_and_with_gsplat_once_loaded():
    """With no build running gsplat draws CUDA tensors; while the build runs, and after it failed, the torch
    rasterizer does (the run never waits under `auto`); the CPU's choice does not depend on the build."""
    assert splat.auto_backend(on_cuda=True, warp_ok=False) == "gsplat"
    release = threading.Event()
    job = start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=lambda: release.wait(10))
    assert splat.auto_backend(on_cuda=True, warp_ok=False) == "torch"
    assert splat.auto_backend(on_cuda=False, warp_ok=True) == "warp"
    assert splat.auto_backend(on_cuda=False, warp_ok=False) == "torch"
    release.set()
    assert _until(lambda: job.done)
    assert splat.auto_backend(on_cuda=True, warp_ok=False) == "gsplat"
    start_gsplat_compile("cuda:0", show=False, needs_compile=lambda: True, compile=lambda: 1 / 0)
    assert _until(lambda: warm_up._pending.done)
    assert splat.auto_backend(on_cuda=True, warp_ok=False) == "torch"  # failed: the run goes on without gsplat


def test_the_build_runs_in_a_session_of_its_own_and_its_failure_names_the_log(tmp_path):
    """The build process is not in this process's session (Ctrl-C, sent to the terminal's foreground group, and
    the run's exit leave it building); a build that exits non-zero is one RenderError at a wait that names its
    last output line and the log; gsplat's no-toolkit exit is the no-toolkit sentence."""
    log = tmp_path / "build.log"
    cmd = [sys.executable, "-c", "import sys, time; time.sleep(0.5); print('nvcc fatal: no GPU arch'); sys.exit(1)"]
    job = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    job.compile = lambda: build_gsplat_detached("cuda:0", job, command=cmd, log=log)
    warm_up._pending = job.start()
    assert _until(lambda: job.process is not None)
    assert os.getsid(job.process.pid) != os.getsid(0) and job.log == log
    with pytest.raises(RenderError) as caught:
        warm_up.wait_for_gsplat()
    message = str(caught.value)
    assert "nvcc fatal: no GPU arch" in message and str(log) in message and "\n" not in message
    toolkit = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    exit3 = [sys.executable, "-c", f"raise SystemExit({warm_up.NO_TOOLKIT_EXIT})"]
    toolkit.compile = lambda: build_gsplat_detached("cuda:0", toolkit, command=exit3, log=log)
    warm_up._pending = toolkit.start()
    with pytest.raises(RenderError, match="found no CUDA toolkit"):
        warm_up.wait_for_gsplat()


@pytest.mark.slow
def test_a_build_that_outlives_the_run_is_announced_and_finishes_after_the_process_exits(tmp_path):
    """A run that ends while the build goes on prints one line naming the build's pid and log, exits at once,
    and the build still finishes afterwards (what the next run loads)."""
    done = tmp_path / "built"
    build = f"import pathlib, time; time.sleep(3.0); pathlib.Path({str(done)!r}).write_text('ok')"
    script = textwrap.dedent(
        f"""
        import sys, time
        from pathlib import Path
        from fracture_gs.render import warm_up as W
        job = W.BackgroundCompile(W.GSPLAT_STEP, None)
        cmd = [sys.executable, "-c", {build!r}]
        job.compile = lambda: W.build_gsplat_detached("cuda:0", job, command=cmd, log=Path({str(tmp_path / "log")!r}))
        W._pending = job.start()
        while job.process is None:
            time.sleep(0.01)
        print(W.detached_notice())
        """
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    line = out.stdout.strip()
    assert line.startswith(f"{warm_up.GSPLAT_STEP}: still building in the background (pid ")
    assert "torch rasterizer" in line and str(tmp_path / "log") in line
    assert not done.exists()  # the run ended without waiting for the build (3 s)
    assert _until(done.exists, 20.0), "the detached build died with the process that started it"


def test_no_notice_once_the_build_is_done_or_when_none_ran(tmp_path):
    """Nothing to say at the run's end when no build ran or it finished within the run."""
    assert warm_up.detached_notice() is None
    job = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    job.compile = lambda: build_gsplat_detached(
        "cuda:0", job, command=[sys.executable, "-c", "pass"], log=tmp_path / "l"
    )
    warm_up._pending = job.start()
    job.wait()
    assert warm_up.detached_notice() is None and warm_up.gsplat_ready()


def test_the_step_says_what_the_frames_do_meanwhile():
    """Under `auto` the compile's line says the frames are drawn with the torch rasterizer meanwhile; a run that
    asked for gsplat is told its first render waits."""
    for waits, expected in ((False, "frames are drawn with the torch rasterizer"), (True, "first render waits")):
        warm_up._pending = None
        text = io.StringIO()
        start_gsplat_compile("cuda:0", file=text, needs_compile=lambda: True, compile=lambda: None, waits=waits)
        assert expected in text.getvalue().splitlines()[0], text.getvalue()
        warm_up._pending.wait()


def test_the_runs_end_waits_for_a_load_in_progress_and_leaves_a_running_build_alone(tmp_path):
    """A finished build being loaded into the run holds torch's build lock for a moment, so the run's end
    (`settle`, also at exit) waits for that load; a build still running is left to its process, and the run does
    not start loading it afterwards (an exit in the middle of a load would leave the lock file behind)."""
    release, loaded = threading.Event(), []
    job = BackgroundCompile(warm_up.GSPLAT_STEP, None)

    def load():
        job.process, job.loading = subprocess.Popen([sys.executable, "-c", "pass"]), True
        job.process.wait()
        release.wait(10)
        loaded.append(True)

    job.compile = load
    warm_up._pending = job.start()
    assert _until(lambda: job.loading)
    settled = threading.Thread(target=warm_up.settle)
    settled.start()
    time.sleep(0.3)
    assert settled.is_alive() and not loaded  # the end waits for the load
    release.set()
    settled.join(5)
    assert loaded == [True] and not settled.is_alive()

    running = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    cmd = [sys.executable, "-c", "import time; time.sleep(0.5)"]
    running.compile = lambda: build_gsplat_detached("cuda:0", running, command=cmd, log=tmp_path / "l")
    warm_up._pending = running.start()
    assert _until(lambda: running.process is not None)
    assert warm_up.settle() is running and running.detached
    assert _until(lambda: running.done)
    assert not running.loading and "the next run loads it" in str(running.error)


def test_a_frame_bar_has_no_eta_until_its_first_frame_is_done_and_leaves_that_frame_out():
    """The first frame loads (on a fresh machine compiles) the kernels: the bar shows no rate and no ETA until it
    is done, then tqdm's own, with that frame's seconds left out of its elapsed time and rate; later frames count."""
    from tqdm import tqdm

    from fracture_gs.render.warm_up import HeldEta

    bar = tqdm(total=10, file=io.StringIO(), mininterval=0)
    eta = HeldEta(bar, waits=False, first_frame=True)
    bar.refresh()
    assert "ETA after the first frame" in str(bar) and "<" not in str(bar)
    time.sleep(0.6)  # the first frame
    eta.check()
    bar.update(1)
    first = eta.held
    assert first >= 0.55 and bar.format_dict["elapsed"] < first, (first, bar.format_dict["elapsed"])
    assert "ETA after" not in str(bar) and "<" in str(bar)
    time.sleep(0.1)  # the second frame: counted
    eta.check()
    bar.update(1)
    assert eta.held == first
    bar.close()


def test_a_run_waits_for_an_earlier_runs_build_instead_of_starting_another(tmp_path):
    """Runs that end before gsplat's build (about 75 s on a fresh machine) leave it building; the next run finds it
    by the pid file beside the log and waits for it rather than start a second build into the same folder (four
    builds at once on an H200 ended in "ninja: build stopped"). It keeps the first build's log, reports the first
    build's pid while it runs, and once that build ends, the next run starts its own again."""
    log = tmp_path / "build.log"
    marker = tmp_path / "second_build_ran"
    first_cmd = [sys.executable, "-c", "import time; print('first build', flush=True); time.sleep(1.5)"]
    second_cmd = [sys.executable, "-c", f"open({str(marker)!r}, 'w').write('x')"]
    first = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    first.compile = lambda: build_gsplat_detached("cuda:0", first, command=first_cmd, log=log)
    first.start()
    assert _until(lambda: first.process is not None and "first build" in log.read_text())
    second = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    second.compile = lambda: build_gsplat_detached("cuda:0", second, command=second_cmd, log=log)
    second.start()
    assert _until(lambda: second.process is not None)
    assert isinstance(second.process, warm_up.EarlierBuild) and second.process.pid == first.process.pid
    assert second.process.poll() is None and not second.done  # waiting for the first build
    assert _until(lambda: first.done and second.done)
    assert first.error is None and second.error is None
    assert not marker.exists() and "first build" in log.read_text()  # no second build, the first one's log kept
    assert warm_up.EarlierBuild.find(log) is None  # it ended: the next run builds again
    third = BackgroundCompile(warm_up.GSPLAT_STEP, None)
    third.compile = lambda: build_gsplat_detached("cuda:0", third, command=second_cmd, log=log)
    third.start()
    assert _until(lambda: third.done) and third.error is None and marker.exists()


def test_an_earlier_build_is_known_by_its_pid_and_start_time(tmp_path):
    """A pid file naming a live process with another start time (the pid reused since) or a dead one is no build;
    only the recorded pid with its recorded start time is."""
    log = tmp_path / "build.log"
    warm_up.EarlierBuild.note(log, os.getpid())
    assert warm_up.EarlierBuild.find(log).pid == os.getpid()
    pid_file = log.with_suffix(".pid")
    pid_file.write_text(f"{os.getpid()} 1\n")  # this pid, but started at another time: a reused pid
    assert warm_up.EarlierBuild.find(log) is None
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    warm_up.EarlierBuild.note(log, dead.pid)
    assert warm_up.EarlierBuild.find(log) is None
    pid_file.write_text("not a pid\n")
    assert warm_up.EarlierBuild.find(log) is None


@pytest.mark.parametrize("env", [None, "set"])
def test_the_build_folder_is_the_one_torch_builds_in(env, tmp_path, monkeypatch):
    """`torch_build_directory` names the folder `torch.utils.cpp_extension._get_build_directory` names (and which
    gsplat's JIT build uses), with and without TORCH_EXTENSIONS_DIR: the quick lookup and torch's agree."""
    from torch.utils.cpp_extension import _get_build_directory

    from fracture_gs.render.warm_up import torch_build_directory

    if env is None:
        monkeypatch.delenv("TORCH_EXTENSIONS_DIR", raising=False)
        monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # torch's default root, without touching ~
    else:
        monkeypatch.setenv("TORCH_EXTENSIONS_DIR", str(tmp_path / "ext"))
    assert torch_build_directory("gsplat_cuda") == _get_build_directory("gsplat_cuda", verbose=False)


@pytest.mark.parametrize("env", ["TORCH_EXTENSIONS_DIR", "torch's default folder"])
def test_a_cached_build_is_found_without_importing_gsplat(env, tmp_path):
    """With a `.so` in the build folder, `gsplat_needs_compile` says no build is needed and leaves gsplat and
    `cpp_extension` unimported (checked in a fresh interpreter); with the folder empty it says a build is needed.
    Both where TORCH_EXTENSIONS_DIR names the folder and in torch's default one: there the lookup needs a torch
    submodule that `import torch` alone does not load, which a fresh process (a user's run) does not have, so the
    fresh interpreter also checks its folder against torch's own `_get_build_directory`, asked afterwards (the
    lookup failed there once and said "no build needed" on every fresh GPU machine)."""
    env_vars = dict(os.environ)
    if env == "TORCH_EXTENSIONS_DIR":
        ext = tmp_path / "ext"
        env_vars["TORCH_EXTENSIONS_DIR"] = str(ext)
    else:
        env_vars.pop("TORCH_EXTENSIONS_DIR", None)
        env_vars["XDG_CACHE_HOME"] = str(tmp_path / "cache")  # torch's default root, without touching ~
        ext = None
    probe = (
        "import sys, torch\n"
        "from fracture_gs.render.warm_up import gsplat_needs_compile, torch_build_directory\n"
        "need = gsplat_needs_compile()\n"
        "print(need, 'gsplat' in sys.modules, 'torch.utils.cpp_extension' in sys.modules)\n"
        "from torch.utils.cpp_extension import _get_build_directory\n"
        "print(torch_build_directory('gsplat_cuda') == _get_build_directory('gsplat_cuda', verbose=False))\n"
        "print(_get_build_directory('gsplat_cuda', verbose=False))\n"
    )

    def ask() -> list[str]:
        out = subprocess.run([sys.executable, "-c", probe], env=env_vars, capture_output=True, text=True)
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.strip().splitlines()

    first = ask()
    assert first[0] == "True False False" and first[1] == "True", first
    folder = Path(first[2])
    assert ext is None or folder == ext / "gsplat_cuda"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "gsplat_cuda.so").write_bytes(b"")
    assert ask()[:2] == ["False False False", "True"]
