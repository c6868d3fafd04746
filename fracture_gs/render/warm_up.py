"""gsplat's one-time CUDA compile, started in the background as a run starts; the run draws with the torch rasterizer
until it is done.

gsplat builds its CUDA code the first time it is used on a machine (torch's JIT extension build, run by importing
`gsplat.cuda._backend`: about a minute and a half on a fresh H200, then cached). Left to the first render, the whole
run stood still for it after setting up. A run instead starts it at once (`start_gsplat_compile`) in a process of
its own (`build_gsplat_detached`: its own session, so neither Ctrl-C nor the run's exit stops it), watched by a
daemon thread that loads the finished build into this process. Meanwhile the scene's set-up, Warp's module loads
and the frames go on, and `render.splat`'s `auto` backend draws CUDA frames with the torch rasterizer (the same
math, 98–136 dB from gsplat's images) until gsplat is loaded; a build that outlives the run goes on and is cached
for the next one (`detached_notice` says so). A build that failed leaves the run on the torch rasterizer; only a
run that asked for `render.backend = 'gsplat'` waits for the build (`wait_for_gsplat`) and gets its failure as one
`RenderError`. Ctrl-C (the run's stop event) ends a wait at once.

While it builds, the compile is a step of its own on the terminal (`CompileStep`: its own line, "elapsed Xs",
below the variants' bars). A run that waits for it (`render.backend = 'gsplat'`) hides a variant's ETA until the
build is done, then leaves the wait out of its rate (`HeldEta`): frames held up by a compile say nothing about
the frames still to come.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Optional

from ..errors import RenderError

GSPLAT_STEP = "gsplat CUDA compile (one time)"
WAITING_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, ETA once gsplat's compile is done{postfix}]"
"""A frame bar's look while a compile may hold its frames up: no rate, no ETA (tqdm's default otherwise)."""
FIRST_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, ETA after the first frame{postfix}]"
"""A frame bar's look until its first frame is done (kernel loads, graph captures): no rate, no ETA."""


def _one_line(exc: BaseException) -> str:
    """The first line of an exception's message (a failed build's message holds the compiler's whole log)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    text = lines[0].rstrip(":") if lines else type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


class CompileStep:
    """The compile as a step of the progress display: on a terminal a line of its own (a tqdm bar at `position`,
    below the variants' bars) that says "elapsed Xs" until `close`; in a log one line when it starts. `close`
    writes the outcome as one line above the bars."""

    def __init__(self, what: str, file=None, position: int = 1, bar: Optional[bool] = None, meanwhile: str = ""):
        from tqdm import tqdm

        self.what, self.file = what, file if file is not None else sys.stderr
        meanwhile = meanwhile or "the run goes on meanwhile and its first render waits for it"
        self.bar = None
        if bar if bar is not None else self.file.isatty():
            self.bar = tqdm(
                total=None,
                desc=what,
                position=position,
                leave=False,
                file=self.file,
                bar_format="{desc} … elapsed {elapsed}",
                mininterval=0.5,
            )
        else:
            tqdm.write(f"{what}: started; {meanwhile}", file=self.file)

    def tick(self) -> None:
        """Redraw the line (its elapsed time)."""
        if self.bar is not None:
            self.bar.refresh()

    def close(self, seconds: Optional[float], error: Optional[BaseException]) -> None:
        """Clear the line and write the outcome (`seconds` None: the run was interrupted; nothing to say)."""
        from tqdm import tqdm

        if self.bar is not None:
            self.bar.close()
        if seconds is None:
            return
        if error is None:
            outcome = f"done in {seconds:.1f} s (cached for later runs)"
        else:
            outcome = f"failed after {seconds:.1f} s: {_one_line(error)}"
        tqdm.write(f"{self.what}: {outcome}", file=self.file)


class BackgroundCompile:
    """`compile()` run once on a daemon thread; `wait()` blocks until it is done and raises its failure as one
    `RenderError`. `cancel`: an Event (a run's stop event, which Ctrl-C sets) that ends a wait at once with
    KeyboardInterrupt. `step`: the progress display (`CompileStep`) ticked while the compile runs, or None."""

    def __init__(
        self,
        what: str,
        compile: Callable[[], None],
        cancel: Optional[threading.Event] = None,
        step: Optional[CompileStep] = None,
        tick: float = 0.5,  # seconds between redraws of the step's line
    ):
        self.what, self.compile, self.cancel, self.step, self.tick = what, compile, cancel, step, tick
        self.process: Optional[subprocess.Popen] = None  # the detached build, once started (`build_gsplat_detached`)
        self.log: Optional[Path] = None  # its output
        self.error: Optional[BaseException] = None
        self.detached = False  # the run ended while the build went on (`settle`): the build is left to the next run
        self.loading = False  # the finished build is being loaded into this process (torch's build lock held)
        self._handoff = threading.Lock()  # between the watcher starting a load and the run's end leaving it
        self.seconds: Optional[float] = None  # the compile's duration, once done
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fgs-compile", daemon=True)

    def start(self) -> BackgroundCompile:
        self.started = time.perf_counter()
        self._thread.start()
        if self.step is not None:
            threading.Thread(target=self._show, name="fgs-compile-step", daemon=True).start()
        return self

    def _run(self) -> None:
        try:
            self.compile()
        except BaseException as exc:  # noqa: BLE001 - raised by `wait` in the thread that renders
            self.error = exc
        finally:
            self.seconds = time.perf_counter() - self.started
            self._done.set()

    def _show(self) -> None:
        while not self._done.wait(self.tick):
            if self.detached or (self.cancel is not None and self.cancel.is_set()):  # the run ended: the line goes
                self.step.close(None, None)
                return
            self.step.tick()
        self.step.close(None if self.detached else self.seconds, self.error)  # a build left to the next run: no word

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self) -> None:
        """Block until the compile is done (at once if it is); raise its failure as one RenderError. From the
        compile's own thread (its test render) it returns at once."""
        if threading.current_thread() is self._thread:
            return
        while not self._done.wait(0.1):
            if self.cancel is not None and self.cancel.is_set():
                raise KeyboardInterrupt(f"interrupted while waiting for the {self.what}")
        if isinstance(self.error, RenderError):  # already one sentence (no CUDA toolkit): a copy per waiting thread
            raise RenderError(str(self.error)) from self.error
        if self.error is not None:
            raise RenderError(
                f"the {self.what} failed ({_one_line(self.error)}); check the CUDA toolkit with "
                "`fracture-gs info --warm-up`, or render on the torch rasterizer with render.backend = 'torch'"
            ) from self.error


_pending: Optional[BackgroundCompile] = None
_pending_lock = threading.Lock()


def start_gsplat_compile(
    device: str,
    cancel: Optional[threading.Event] = None,
    show: bool = True,
    position: int = 1,
    needs_compile: Optional[Callable[[], bool]] = None,
    compile: Optional[Callable[[], None]] = None,
    file=None,
    waits: bool = False,
) -> Optional[BackgroundCompile]:
    """Start gsplat's one-time build for `device` in the background, if it needs one (`needs_compile`, default
    `gsplat_needs_compile`); returns it, or None when nothing was started (the CPU, or a build already
    there). One per process: a build still running is reused (with this run's `cancel`), a failed one retried.
    `show`: draw it as its own step (`CompileStep` at line `position`, on `file`, default stderr). `compile`
    replaces `build_gsplat_detached` (tests). `waits`: the run's frames wait for the build (`render.backend =
    'gsplat'`); else they are drawn with the torch rasterizer meanwhile, and the step says which."""
    global _pending
    if not str(device).startswith("cuda"):
        return None
    if needs_compile is None:
        needs_compile = gsplat_needs_compile
    with _pending_lock:
        if _pending is not None and not _pending.done:
            _pending.cancel = cancel
            return _pending
        _pending = None  # a finished one: a success needs no build now, a failure is tried again
        if not needs_compile():
            return None
        meanwhile = "" if waits else "frames are drawn with the torch rasterizer until it is done"
        step = CompileStep(GSPLAT_STEP, file=file, position=position, meanwhile=meanwhile) if show else None
        job = BackgroundCompile(GSPLAT_STEP, compile, cancel=cancel, step=step)
        if compile is None:
            job.compile = lambda: build_gsplat_detached(device, job)
            atexit.unregister(settle)  # once per process, however many runs start a build
            atexit.register(settle)  # any exit, not only a run's end: never cut a load short
        _pending = job.start()
        return _pending


def pending_compile() -> Optional[BackgroundCompile]:
    """The background compile while it runs, else None."""
    job = _pending
    return job if job is not None and not job.done else None


def wait_for_gsplat() -> None:
    """Wait for the background compile, if one was started (at once if it is done); raises its failure."""
    job = _pending
    if job is not None:
        job.wait()


class HeldEta:
    """A variant's frame bar while something may hold its frames up: no ETA until it is over, then tqdm's own
    again, with the wait left out of the bar's rate and elapsed time (`tqdm.unpause` from the last redraw).
    `held`: the seconds left out, for the caller's own rates. What holds the frames:

    * a background compile they wait for (`WAITING_FORMAT` until it is done); `waits` False (a run that draws with
      the torch rasterizer meanwhile): no compile holds them;
    * `first_frame`: the first frame, which loads (on a fresh machine compiles) the Warp modules and records the
      CUDA graphs: its seconds say nothing about the frames to come (`FIRST_FORMAT` until it is done; a fresh
      H200's first frame took 11 s and the next 0.1 s each, and tqdm read "16:44" left for a 50 s run)."""

    def __init__(self, bar, compile: Optional[BackgroundCompile] = None, waits: bool = True, first_frame: bool = False):
        self.bar, self.compile = bar, compile if compile is not None else pending_compile() if waits else None
        self.first = first_frame
        self.held = 0.0
        if self.compile is not None or self.first:
            self._format = bar.bar_format
            bar.bar_format = WAITING_FORMAT if self.compile is not None else FIRST_FORMAT

    def check(self) -> None:
        """Before each update: once the first frame is done (`first_frame`) and the compile is (if one holds the
        frames), give the bar its ETA back without the wait."""
        first, self.first = self.first, False
        if self.compile is not None and not self.compile.done:
            if first:
                self._leave_out()  # the first frame's seconds go; the bar stays without an ETA for the compile
            return
        if first or self.compile is not None:
            self._leave_out()
            self.bar.bar_format = self._format
            self.compile = None

    def _leave_out(self) -> None:
        before = self.bar.start_t
        self.bar.unpause()
        self.held += self.bar.start_t - before


@contextlib.contextmanager
def _no_spinner():
    """gsplat draws a rich spinner on stdout while it builds; a run shows the build as its own step instead, and
    two animations on one terminal garble each other. Rich animates only on an interactive terminal, which
    `TTY_INTERACTIVE=0` (rich's own switch) turns off; a value the user set is kept."""
    if "TTY_INTERACTIVE" in os.environ:
        yield
        return
    os.environ["TTY_INTERACTIVE"] = "0"
    try:
        yield
    finally:
        os.environ.pop("TTY_INTERACTIVE", None)


NO_TOOLKIT = (
    "gsplat found no CUDA toolkit (nvcc) to build its CUDA code with; install the CUDA toolkit "
    "(or a gsplat wheel with prebuilt kernels), or render with render.backend = 'torch'"
)
NO_TOOLKIT_EXIT = 3  # the detached build's exit status when gsplat found no toolkit
BUILD_SCRIPT = (
    f"import sys\nfrom gsplat.cuda import _backend\nsys.exit(0 if _backend._C is not None else {NO_TOOLKIT_EXIT})\n"
)
"""The detached build: importing `gsplat.cuda._backend` is what builds gsplat's CUDA code (torch's JIT build)."""


def build_log() -> Path:
    """Where the detached build writes its output (one file per user, replaced by each build)."""
    import tempfile

    return Path(tempfile.gettempdir()) / f"fracture_gs_gsplat_build_{os.getuid()}.log"


class EarlierBuild:
    """A detached build that an earlier run started and that still runs (found by the pid file beside its log, and
    the process's start time, so a reused pid is not taken for it): `pid`, `poll()` (None while it runs) and `wait()`,
    as much of `subprocess.Popen` as a run needs of its build. Runs on a fresh machine that end before the build
    (about 75 s) would otherwise each start another: measured on an H200, four 25–40 s runs in a row started four
    builds into one folder, none finished, and the log ended "ninja: build stopped: subcommand failed"."""

    def __init__(self, pid: int):
        self.pid = pid

    @staticmethod
    def _started(pid: int) -> Optional[str]:
        """The process's start time in clock ticks since boot (`/proc/PID/stat`), or None if there is none."""
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return None
        fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) ": state is field 3, starttime field 22
        return fields[19] if len(fields) > 19 and fields[0] not in ("Z", "X") else None

    @classmethod
    def note(cls, log: Path, pid: int) -> None:
        """Record a build just started, for later runs to find (`find`)."""
        with contextlib.suppress(OSError):
            log.with_suffix(".pid").write_text(f"{pid} {cls._started(pid) or ''}\n")

    @classmethod
    def find(cls, log: Path) -> Optional[EarlierBuild]:
        """The build recorded beside `log` if that process still runs, else None."""
        try:
            pid_text, *started = log.with_suffix(".pid").read_text().split()
            pid = int(pid_text)
        except (OSError, ValueError):
            return None
        now = cls._started(pid)
        return cls(pid) if now is not None and started == [now] else None

    def poll(self) -> Optional[int]:
        return None if self._started(self.pid) is not None else 0

    def wait(self, tick: float = 0.5) -> int:
        while self.poll() is None:
            time.sleep(tick)
        return 0


def build_gsplat_detached(
    device: str, job: Optional[BackgroundCompile] = None, command: Optional[list] = None, log: Optional[Path] = None
) -> None:
    """gsplat's CUDA build run in a process of its own session (`command`, default `BUILD_SCRIPT`): neither Ctrl-C
    (sent to the terminal's process group) nor this process's exit stops it, so a build that outlives a short run
    is finished and cached for the next. Waits for it, then loads the build here (`compile_gsplat`, seconds once
    built; skipped for a `command` of a test's). `job`: the BackgroundCompile to note the process and its `log` on.
    Raises RenderError when gsplat found no toolkit, RuntimeError with the log's last line when the build failed."""
    log = build_log() if log is None else log
    earlier = EarlierBuild.find(log)
    if earlier is not None:  # an earlier run's build still runs: a second would collide with it in torch's build folder
        if job is not None:
            job.process, job.log = earlier, log
        earlier.wait()
        code = 0  # its status went to its own parent; whether it built shows when the build is loaded below
    else:
        env = dict(os.environ, TTY_INTERACTIVE="0")  # no rich spinner in the log (`_no_spinner`)
        with open(log, "w") as out:
            proc = subprocess.Popen(
                command or [sys.executable, "-c", BUILD_SCRIPT],
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,
            )
        EarlierBuild.note(log, proc.pid)
        if job is not None:
            job.process, job.log = proc, log
        code = proc.wait()
    if code == NO_TOOLKIT_EXIT:
        raise RenderError(NO_TOOLKIT)
    if code != 0:
        tail = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
        raise RuntimeError(f"the build exited with status {code}: {tail[-1] if tail else 'no output'} (log: {log})")
    if job is not None:
        with job._handoff:
            if job.detached:  # the run is ending: a load cut short by the exit could leave torch's lock file behind
                raise RuntimeError("the run ended before the finished build was loaded; the next run loads it")
            job.loading = True
    if command is None:
        compile_gsplat(device, spinner=False)


def draw_without_gsplat(why: str) -> None:
    """From now on `gsplat_ready()` is False in this process, so `auto` draws CUDA frames with the torch rasterizer:
    for a worker forked before its parent started gsplat's build (the build is the parent's; loading it here while
    it is written would fail). `why`: the reason, kept as the job's error."""
    global _pending
    job = BackgroundCompile(GSPLAT_STEP, lambda: None)
    job.error = RenderError(why)
    job._done.set()
    with _pending_lock:
        _pending = job


def gsplat_ready() -> bool:
    """False while a background build runs or after it failed: the `auto` backend then draws CUDA frames with the
    torch rasterizer rather than wait (`render.splat.render`)."""
    job = _pending
    return job is None or (job.done and job.error is None)


def settle(timeout: float = 60.0) -> Optional[BackgroundCompile]:
    """At a run's end (and at exit): a build being loaded into this process is waited for (the load holds torch's
    build lock for a moment, and a lock file left by an exit would stall every later run); a build still running
    is left to its own process, and this process will not load it. Returns the job left running, else None."""
    job = _pending
    if job is None or job.done or job.process is None:
        return None
    with job._handoff:
        if not job.loading:
            job.detached = True
    if job.loading:
        job._done.wait(timeout)
        return None
    return job if job.process.poll() is None else None


def detached_notice() -> Optional[str]:
    """At a run's end, the sentence to print when its gsplat build still runs in its own process, else None
    (`settle` first)."""
    job = settle()
    if job is None:
        return None
    return (
        f"{GSPLAT_STEP}: still building in the background (pid {job.process.pid}, log {job.log}); this run drew "
        "with the torch rasterizer, and the next run draws with gsplat once the build is done"
    )


def compile_gsplat(device: str, spinner: bool = True) -> None:
    """gsplat's CUDA code built (or loaded from its cache) and run once on `device`: importing
    `gsplat.cuda._backend` is what builds it; a rasterization of three Gaussians then loads its kernels on the
    device (on the render stream, under `runtime.capture_lock`: never inside another thread's CUDA graph
    capture). Raises RenderError when gsplat found no CUDA toolkit to build with."""
    import torch

    with contextlib.nullcontext() if spinner else _no_spinner():
        from gsplat.cuda import _backend
    if _backend._C is None:
        raise RenderError(NO_TOOLKIT)
    import gsplat

    from ..runtime import capture_lock, side_stream

    dev = torch.device(device)
    with capture_lock, torch.cuda.device(dev), torch.cuda.stream(side_stream(dev, "render")):
        means = torch.tensor([[0.0, 0.0, 2.0], [0.1, 0.0, 2.5], [-0.1, 0.05, 3.0]], device=dev)  # [3, 3]
        covars = 1e-3 * torch.eye(3, device=dev).expand(3, 3, 3).contiguous()  # [3, 3, 3]
        K = torch.tensor([[16.0, 0.0, 8.0], [0.0, 16.0, 8.0], [0.0, 0.0, 1.0]], device=dev)  # [3, 3]
        gsplat.rasterization(
            means,
            None,
            None,
            torch.full((3,), 0.5, device=dev),  # opacities [3]
            torch.rand(3, 3, device=dev),  # colours [3, 3]
            torch.eye(4, device=dev)[None],  # view matrix [1, 4, 4]
            K[None],
            16,
            16,
            packed=False,
            covars=covars,
        )
        torch.cuda.current_stream(dev).synchronize()


def torch_build_directory(name: str) -> str:
    """The folder torch's JIT builds extension `name` in, as `torch.utils.cpp_extension._get_build_directory` names it
    (TORCH_EXTENSIONS_DIR, else torch's user cache folder with the Python and accelerator versions), without importing
    `cpp_extension` (setuptools: 0.1–0.4 s) and without creating the folder. A test holds the two to the same path."""
    import torch
    from torch._appdirs import user_cache_dir  # a submodule `import torch` does not load (cpp_extension does)

    root = os.environ.get("TORCH_EXTENSIONS_DIR")
    if root is None:
        if torch.version.hip is not None:
            accelerator = f"rocm{torch.version.hip.replace('.', '')}"
        elif torch.version.cuda is not None:
            accelerator = f"cu{torch.version.cuda.replace('.', '')}"
        else:
            accelerator = "cpu"
        python = f"py{sys.version_info.major}{sys.version_info.minor}{getattr(sys, 'abiflags', '')}"
        cache = os.path.realpath(user_cache_dir(appname="torch_extensions"))
        root = os.path.join(cache, f"{python}_{accelerator}")
    return os.path.join(root, name)


def gsplat_needs_compile() -> bool:
    """True when gsplat is installed with neither a prebuilt `gsplat.csrc` beside it nor a `.so` of its JIT build in
    the folder torch builds it in (`torch_build_directory`), so its first rasterization will compile (about a
    minute). Looked up without importing gsplat or `cpp_extension` (a warm run paid 0.42 s of those imports)."""
    import glob
    import importlib.machinery
    import importlib.util

    try:
        spec = importlib.util.find_spec("gsplat")  # the top-level package is found, not imported
        if spec is None or not spec.submodule_search_locations:
            return False  # no gsplat: nothing to build
        if importlib.machinery.PathFinder.find_spec("csrc", list(spec.submodule_search_locations)) is not None:
            return False
        build = torch_build_directory("gsplat_cuda")
    except Exception:  # noqa: BLE001 - unknown layout: say nothing rather than mislead
        return False
    return not glob.glob(os.path.join(build, "*.so"))
