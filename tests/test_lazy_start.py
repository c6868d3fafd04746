"""Start-up (issue 36): the commands that only read (--help, --version, info, validate, every refused flag) load
none of torch, Warp, gsplat, matplotlib, scipy or cv2; `info` finds what it reports without them; `--profile`
reports start-up (imports, Warp init, kernel module loads) as rows of their own; a second run loads every Warp
kernel module from the cache, and a CPU run never imports gsplat or matplotlib."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fracture_gs.cli import devices, hardware
from fracture_gs.io import detect, splat_file
from fracture_gs.profiling import PhaseTimer, process_seconds

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "warp", "gsplat", "matplotlib", "scipy", "cv2")

LIGHT_COMMANDS = """
import json, sys
HEAVY = {heavy!r}
import fracture_gs.cli as cli
report = {{"import fracture_gs.cli": [sorted(m for m in HEAVY if m in sys.modules), 0]}}
for argv in {commands!r}:
    code = cli.main(argv)
    report[" ".join(argv)] = [sorted(m for m in HEAVY if m in sys.modules), code]
print(json.dumps(report), file=sys.stderr)
"""

COMMANDS = [
    ["--help"],
    ["--version"],
    ["render-sim", "--help"],
    ["bench", "--help"],
    ["figures", "--help"],
    ["sweep", "--help"],
    ["init", "--help"],
    ["validate", "--help"],
    ["validate", "bread"],
    ["validate", "exp_table5_bread_vlm", "--dump"],
    ["info"],
    ["render-sim"],  # argparse: CONFIG missing
    ["bench", "--bogus"],  # argparse: unknown flag
    ["render-sim", "bread", "--device", "gpu"],  # a device that is no device
    ["render-sim", "bread", "--variants", "baseline,fulll"],  # a config check, with --device auto
    ["render-sim", "bread", "--load", "drop", "--device", "cpu"],  # a flag that would do nothing
]
EXPECTED_CODE = {"render-sim": 2, "bench --bogus": 2}


def _child(script: str, timeout: float = 120, module_dir: Path | None = None) -> subprocess.CompletedProcess:
    """Run `script` in a fresh interpreter (`-c`), or with `module_dir` the module of that name there (`-m`)."""
    path = [str(ROOT)] + ([str(module_dir)] if module_dir else [])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path + [os.environ.get("PYTHONPATH", "")]))
    env.pop("FRACTURE_GS_DEBUG", None)
    return subprocess.run(
        [sys.executable, "-m" if module_dir else "-c", script],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )


def test_reading_commands_import_no_heavy_module():
    """In a fresh interpreter, `import fracture_gs.cli` and then every command that only reads or refuses (help
    of each command, --version, validate of built-in configs, info, argparse errors, a bad device, a bad
    variant with --device auto, a flag that would do nothing) leaves torch, Warp, gsplat, matplotlib, scipy
    and cv2 unimported, and each still ends with its exit code (0, or 2 for the errors): importing any of
    them anywhere on those paths (torch alone takes seconds) fails this test."""
    out = _child(LIGHT_COMMANDS.format(heavy=HEAVY, commands=COMMANDS))
    assert out.returncode == 0, out.stderr[-3000:]
    report = json.loads(out.stderr.strip().splitlines()[-1])
    loaded = {cmd: mods for cmd, (mods, _) in report.items() if mods}
    assert loaded == {}, f"heavy modules imported by: {loaded}"
    codes = {cmd: code for cmd, (_, code) in report.items()}
    for argv in COMMANDS:
        cmd = " ".join(argv)
        want = 2 if cmd in EXPECTED_CODE or cmd.startswith("render-sim bread") else 0
        assert codes[cmd] == want, (cmd, codes[cmd], out.stderr[-2000:])
    assert "ok: config is valid" in out.stdout and "sigma_R = 55.0" in out.stdout  # validate still validates
    assert "did you mean 'full'" in out.stderr and "not a device" in out.stderr


def test_a_cpu_run_loads_only_what_it_uses():
    """Importing what a render-sim run runs (the job, the pipeline, the solver, the renderer) loads neither gsplat
    (CUDA rendering only), matplotlib (figures only) nor scipy (a fracture event's connected pieces load
    scipy.ndimage when the event comes, 0.15–0.4 s a process otherwise spent at start-up)."""
    script = (
        "import sys, json\n"
        "import fracture_gs.render_sim.job, fracture_gs.pipeline, fracture_gs.sim.providers, fracture_gs.render.splat\n"
        "print(json.dumps(sorted(m for m in ('gsplat', 'matplotlib', 'scipy') if m in sys.modules)))\n"
    )
    out = _child(script)
    assert out.returncode == 0, out.stderr[-3000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


def test_torch_cuda_build_is_read_without_importing_torch_and_matches_it():
    """`hardware.torch_cuda_build` parses torch/version.py as text; its answer must be torch's own
    `torch.version.cuda` (None for this CPU-only build, e.g. '12.8' for a CUDA wheel)."""
    import torch

    installed, built = hardware.torch_cuda_build()
    assert installed is True
    assert built == torch.version.cuda


def test_torch_cuda_build_reads_a_cuda_wheel(tmp_path, monkeypatch):
    """A CUDA wheel's version.py (`cuda: Optional[str] = '12.8'`) gives '12.8'; a CPU wheel's (`= None`) None."""
    (tmp_path / "version.py").write_text(
        "from typing import Optional\n__version__ = '2.9.0'\ncuda: Optional[str] = '12.8'\n"
    )
    monkeypatch.setattr(hardware, "_package_dir", lambda module: str(tmp_path))
    assert hardware.torch_cuda_build() == (True, "12.8")
    (tmp_path / "version.py").write_text("cuda = None\nhip = None\n")
    assert hardware.torch_cuda_build() == (True, None)


def test_cuda_status_follows_torchs_rules(monkeypatch):
    """torch sees CUDA only with a CUDA build, a driver that reports a device, and a driver of at least torch's
    CUDA major version: each missing piece says why and picks the CPU; all present picks the GPU."""
    gpu = [("NVIDIA H100 80GB HBM3", 79.2, "sm_90")]
    monkeypatch.setattr(hardware, "torch_cuda_build", lambda: (True, None))
    assert hardware.cuda_status() == (False, "CPU-only torch build", [])
    monkeypatch.setattr(hardware, "torch_cuda_build", lambda: (False, None))
    assert hardware.cuda_status()[:2] == (False, "torch is not installed")
    monkeypatch.setattr(hardware, "torch_cuda_build", lambda: (True, "12.8"))
    monkeypatch.setattr(hardware, "driver_devices", lambda: (None, [], "no CUDA driver (libcuda not found)"))
    available, reason, _ = hardware.cuda_status()
    assert not available and "no CUDA driver" in reason and "12.8" in reason
    monkeypatch.setattr(hardware, "driver_devices", lambda: (11080, gpu, ""))
    available, reason, _ = hardware.cuda_status()
    assert not available and "11.8" in reason and "update the driver" in reason
    monkeypatch.setattr(hardware, "driver_devices", lambda: (12040, gpu, ""))
    assert hardware.cuda_status() == (True, "1 device(s), CUDA 12.8 (driver 12.4)", gpu)


def test_a_driver_that_cannot_be_queried_leaves_the_answer_to_torch(monkeypatch):
    """A CUDA driver library without the symbols the probe calls (AttributeError from ctypes) is no reason to
    report the CPU: `info` then asks torch, as a run does, and lists torch's devices."""
    import types

    import torch

    def unreadable():
        raise AttributeError("libcuda.so.1: undefined symbol: cuDeviceTotalMem_v2")

    props = types.SimpleNamespace(name="NVIDIA H200", total_memory=140 * 2**30, major=9, minor=0)
    monkeypatch.setattr(hardware, "torch_cuda_build", lambda: (True, "13.0"))
    monkeypatch.setattr(hardware, "driver_devices", unreadable)
    monkeypatch.setattr(devices, "_cuda_devices", lambda: (True, 1, "torch.cuda.is_available() is True"))
    monkeypatch.setattr(torch.cuda, "get_device_properties", lambda i: props)
    assert hardware.cuda_status() == (True, "torch.cuda.is_available() is True", [("NVIDIA H200", 140.0, "sm_90")])


def test_warp_cache_dir_is_warps_own_choice(monkeypatch):
    """Without importing Warp, `info` names the folder Warp's own appdirs picks (~/.cache/warp/<version> on
    Linux), and WARP_CACHE_PATH/<version> when that variable is set, as `warp.init()` does."""
    import warp as wp
    from warp._src.build import appdirs

    monkeypatch.delenv("WARP_CACHE_PATH", raising=False)
    assert hardware.warp_cache_dir() == appdirs.user_cache_dir(
        appname="warp", appauthor="NVIDIA", version=wp.config.version
    )
    monkeypatch.setenv("WARP_CACHE_PATH", "/tmp/some/where")
    assert hardware.warp_cache_dir().split()[0] == os.path.join("/tmp/some/where", wp.config.version)


def test_the_light_splat_row_size_is_the_readers():
    """`detect` recognises a .splat file by its 32-byte rows without importing splat_file (numpy): the two
    row sizes must agree."""
    assert detect.SPLAT_ROW_BYTES == splat_file.ROW_BYTES == splat_file.ROW.itemsize


def test_process_seconds_counts_from_the_process_start():
    """`process_seconds()` at the end of a child that slept 0.3 s is at least 0.3 s and at most the time the
    parent waited for the whole child (it counts from the child's start, not from an import)."""
    t0 = time.perf_counter()
    out = _child(
        "import time; time.sleep(0.3); from fracture_gs.profiling import process_seconds; print(process_seconds())"
    )
    waited = time.perf_counter() - t0
    assert out.returncode == 0, out.stderr
    seconds = float(out.stdout.split()[-1])
    assert 0.3 <= seconds <= waited + 0.02  # /proc counts in 10 ms ticks
    assert process_seconds() > 0.0


WARP_LOAD_LINES = [
    "Module fracture_gs.linalg 58d5dbd load on device 'cpu' took 2.11 ms  (cached)",
    "Module fracture_gs.sim.clock 8522f54 load on device 'cpu' took 1500.00 ms  (compiled)",
    "Module fracture_gs.sim.clock 8522f54 load on device 'cuda:0' (block_dim=256) took 3.50 ms  (cached)",
    "Warp 1.19.0 initialized:",
    "Module broken 1234567 load on device 'cpu' took 4.00 ms  (error)",
]


def test_warp_module_load_lines_become_profile_rows(monkeypatch):
    """The CLI's Warp logger turns Warp's module load lines of a profiled run into the "module loads" row:
    count, seconds, how many came from the kernel cache and how many compiled (other lines and failed loads
    are not loads); with profiling off it notes nothing. The report shows the row once, then forgets it."""
    timer = PhaseTimer()
    monkeypatch.setattr("fracture_gs.profiling.phases", timer)
    quiet = devices._QuietWarpLogger(inner=None)
    for line in WARP_LOAD_LINES:
        quiet.info(line)
    assert timer.startup == {}
    timer.enable()
    for line in WARP_LOAD_LINES:
        quiet.info(line)
    seconds, count, compiled = timer.startup["module loads"]
    assert (count, compiled) == (3, 1) and seconds == pytest.approx(1.50561)
    report = timer.report()
    assert re.search(r"\| module loads \(2 cached, 1 compiled\) \| 1\.51 \| \d+ \| 3 \|", report), report
    assert "module loads" not in timer.report()


def test_startup_rows_come_before_the_phases_and_outside_the_wall():
    """Imports and Warp init, noted before the run enables the timer, are reported first, marked as before
    the run (no share of its wall time), and summed into the header; the phases follow as before."""
    timer = PhaseTimer()
    timer.note_startup("imports", 2.25)
    timer.note_startup("warp init", 0.25)
    timer.enable()
    with timer.section("simulate"):
        time.sleep(0.01)
    lines = timer.report().splitlines()
    assert "after 2.50 s of start-up" in lines[0]
    rows = [line for line in lines if line.startswith("| ") and not line.startswith("| phase")]
    assert rows[0] == "| imports | 2.25 | before the run | 1 |"
    assert rows[1] == "| warp init | 0.25 | before the run | 1 |"
    # the section slept 10 ms; a loaded machine wakes it late, so its row says at least that (the value is timed).
    # Its share of the wall is most of it (the start-up is outside the wall: inside, it would be 0.4 %)
    name, seconds, share, count = [cell.strip() for cell in rows[2].strip("|").split("|")]
    assert name == "simulate" and float(seconds) >= 0.01 and int(share) >= 50 and count == "1", rows[2]


RUN_TWICE = """
import json, sys
from fracture_gs.cli import main
HEAVY = {heavy!r}
for out in {outs!r}:
    code = main(["render-sim", "bread", "--device", "cpu", "--frames", "12", "--particles", "2000",
                 "--resolution", "64x48", "--variants", "full", "--profile", "--out", out])
    assert code == 0, code
print(json.dumps(sorted(m for m in HEAVY if m in sys.modules)), file=sys.stderr)
"""


@pytest.mark.slow
def test_a_second_run_loads_every_kernel_module_from_the_cache(tmp_path):
    """Two CPU runs of bread (12 frames: the crack latches, so the fragment kernels load too) in one process,
    then a third in a fresh process: the first run in each process reports its Warp kernel module loads in
    profile.md, and the fresh process's run compiles none (each module's hash is the same in every process,
    so the kernel cache is hit); Warp is initialised once (a "warp init" row in the first run's profile only);
    gsplat and matplotlib are never imported on the CPU."""
    outs = [str(tmp_path / "a"), str(tmp_path / "b")]
    first = _child(RUN_TWICE.format(heavy=HEAVY, outs=outs), timeout=900)
    assert first.returncode == 0, first.stderr[-3000:]
    fresh = _child(RUN_TWICE.format(heavy=HEAVY, outs=[str(tmp_path / "c")]), timeout=900)
    assert fresh.returncode == 0, fresh.stderr[-3000:]
    profiles = {k: (tmp_path / k / "profile.md").read_text() for k in "abc"}
    loads = {k: re.search(r"\| module loads \((\d+) cached, (\d+) compiled\) \|", p) for k, p in profiles.items()}
    assert loads["a"] and loads["c"], profiles
    cached, compiled = int(loads["c"][1]), int(loads["c"][2])
    assert compiled == 0 and cached >= 5, profiles["c"]
    assert loads["b"] is None  # every module was loaded by the first run of that process
    assert "| warp init |" in profiles["a"] and "| warp init |" not in profiles["b"]
    for out in (first, fresh):
        heavy = json.loads(out.stderr.strip().splitlines()[-1])
        assert "gsplat" not in heavy and "matplotlib" not in heavy, heavy
        assert "torch" in heavy and "warp" in heavy  # the run did run


INTERRUPT_IN_EVAL = """
import sys
import fracture_gs.cli as cli

def command(args):
    eval("__import__('os').kill(__import__('os').getpid(), 2) or __import__('time').sleep(5)")
    return 0

cli._commands = lambda: {"info": command}
sys.exit(cli.main(["info"]))
"""


def test_ctrl_c_inside_code_run_from_a_string_still_exits_130(tmp_path):
    """A Ctrl-C that lands in code run by `eval` of a string (inspect evaluates string annotations so, and Warp
    does that while importing) is caught by main() like any other, and `python -m ...` must end with 130:
    CPython remembers a KeyboardInterrupt that escaped such code and, for a module run with -m, kills the
    process by SIGINT (-2) at exit even though the exit code was 130."""
    (tmp_path / "interrupt_in_eval.py").write_text(INTERRUPT_IN_EVAL)
    out = _child("interrupt_in_eval", module_dir=tmp_path)
    assert out.returncode == 130, (out.returncode, out.stderr[-2000:])
    assert "fracture-gs: interrupted;" in out.stderr and "Traceback" not in out.stderr


def test_a_held_interrupt_is_raised_when_the_hold_ends(monkeypatch, capsys, request):
    """Inside `held_interrupts()` (around `import torch`, whose C++ start-up aborts the process on a
    KeyboardInterrupt) a Ctrl-C is recorded, the code goes on, and it is raised when the hold ends: main()
    returns 130 with the one-line message. Outside main() the hold is a no-op and Ctrl-C raises at once."""
    from fracture_gs import cli

    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    request.addfinalizer(lambda: signal.signal(signal.SIGINT, outer))
    went_on = []

    def command(args):
        with cli.held_interrupts():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)  # the handler runs here and must not raise
            went_on.append(True)
        went_on.append("after the hold")  # never reached: the hold's end raises
        return 0

    monkeypatch.setattr(cli, "_commands", lambda: {"info": command})
    assert cli.main(["info"]) == 130
    assert went_on == [True]
    assert "fracture-gs: interrupted; nothing was written." in capsys.readouterr().err
    with pytest.raises(KeyboardInterrupt):
        with cli.held_interrupts():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)


FINISH_PROBE = """
import atexit, sys, threading, time
if sys.argv[2] == "torch":
    import torch  # noqa: F401
from fracture_gs.cli import finish
out = sys.argv[1]

class Teardown:  # its finaliser runs in the interpreter's teardown, which the fast exit skips
    def __init__(self):
        import os
        self.fd, self.write = os.open(out + "/teardown", os.O_WRONLY | os.O_CREAT), os.write  # kept: builtins go first
    def __del__(self):
        self.write(self.fd, b"ran")

keep = Teardown()
def late():
    time.sleep(0.3)
    open(out + "/thread", "w").write("done")
threading.Thread(target=late).start()  # not a daemon: the process must wait for it
atexit.register(lambda: open(out + "/atexit", "w").write("ran"))
for _ in range(1000):
    sys.stdout.write("x" * 100)  # small writes, no newline: the last few thousand are still in the buffer
finish(3)
"""


@pytest.mark.parametrize("loaded", ["torch", "nothing"])
def test_the_program_ends_without_teardown_once_torch_is_loaded(loaded, tmp_path):
    """`cli.finish`, how the program ends: the exit code given, a thread that is not a daemon finished, the
    atexit handlers run and stdout flushed, as at a plain exit. With torch loaded the interpreter's teardown is
    skipped (0.65 s of finalising torch and Warp after a CPU run): an object's finaliser that runs only in the
    teardown does not run. Without torch (--help, info, early errors) it is a plain exit, teardown included."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    env.pop("PYTHONUNBUFFERED", None)  # stdout block-buffered, as into a pipe or file by default
    out = subprocess.run(
        [sys.executable, "-c", FINISH_PROBE, str(tmp_path), loaded],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 3, out.stderr[-2000:]
    assert out.stdout == "x" * 100000
    assert (tmp_path / "thread").read_text() == "done" and (tmp_path / "atexit").read_text() == "ran"
    assert (tmp_path / "teardown").read_text() == ("ran" if loaded == "nothing" else "")
