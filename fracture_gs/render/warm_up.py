"""gsplat's one-time CUDA compile, started in the background as a run starts, and waited for by the first render.

gsplat builds its CUDA code the first time it is used on a machine (torch's JIT extension build, run by importing
`gsplat.cuda._backend`: about a minute, then cached). Left to the first render, the whole run stood still for it
after setting up. A run instead starts it on a daemon thread at once (`start_gsplat_compile`): the scene's set-up,
Warp's module loads and the first frames go on meanwhile, and the first gsplat render waits for the build
(`wait_for_gsplat`, called by `render.splat`). A build that failed is raised there as one `RenderError`; Ctrl-C
(the run's stop event) ends a wait at once, and the thread, a daemon, never keeps the process alive.

While it builds, the compile is a step of its own on the terminal (`CompileStep`: its own line, "elapsed Xs",
below the variants' bars), and a variant's bar hides its ETA until the build is done, then leaves the wait out
of its rate (`HeldEta`): frames held up by a compile say nothing about the frames still to come.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from typing import Callable, Optional

from ..errors import RenderError

GSPLAT_STEP = "gsplat CUDA compile (one time)"
WAITING_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}, ETA once gsplat's compile is done{postfix}]"
"""A frame bar's look while a compile may hold its frames up: no rate, no ETA (tqdm's default otherwise)."""


def _one_line(exc: BaseException) -> str:
    """The first line of an exception's message (a failed build's message holds the compiler's whole log)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    text = lines[0].rstrip(":") if lines else type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


class CompileStep:
    """The compile as a step of the progress display: on a terminal a line of its own (a tqdm bar at `position`,
    below the variants' bars) that says "elapsed Xs" until `close`; in a log one line when it starts. `close`
    writes the outcome as one line above the bars."""

    def __init__(self, what: str, file=None, position: int = 1, bar: Optional[bool] = None):
        from tqdm import tqdm

        self.what, self.file = what, file if file is not None else sys.stderr
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
            tqdm.write(f"{what}: started; the run goes on meanwhile and its first render waits for it", file=self.file)

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
        self.error: Optional[BaseException] = None
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
            if self.cancel is not None and self.cancel.is_set():  # the run was interrupted: the line goes
                self.step.close(None, None)
                return
            self.step.tick()
        self.step.close(self.seconds, self.error)

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
) -> Optional[BackgroundCompile]:
    """Start gsplat's one-time build for `device` in the background, if it needs one (`needs_compile`, default
    `gsplat_needs_compile`); returns it, or None when nothing was started (the CPU, or a build already
    there). One per process: a build still running is reused (with this run's `cancel`), a failed one retried.
    `show`: draw it as its own step (`CompileStep` at line `position`, on `file`, default stderr). `compile`
    replaces `compile_gsplat` (tests)."""
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
        step = CompileStep(GSPLAT_STEP, file=file, position=position) if show else None
        job = compile if compile is not None else (lambda: compile_gsplat(device, spinner=False))
        _pending = BackgroundCompile(GSPLAT_STEP, job, cancel=cancel, step=step).start()
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
    """A variant's frame bar while a background compile may hold its frames up: no ETA until the compile is done
    (`WAITING_FORMAT`), then tqdm's own again, with the wait left out of the bar's rate and elapsed time
    (`tqdm.unpause` from the last redraw). `held`: the seconds left out, for the caller's own rates."""

    def __init__(self, bar, compile: Optional[BackgroundCompile] = None):
        self.bar, self.compile = bar, compile if compile is not None else pending_compile()
        self.held = 0.0
        if self.compile is not None:
            self._format = bar.bar_format
            bar.bar_format = WAITING_FORMAT

    def check(self) -> None:
        """Before each update: once the compile is done, give the bar its ETA back without the wait."""
        if self.compile is None or not self.compile.done:
            return
        before = self.bar.start_t
        self.bar.unpause()
        self.held += self.bar.start_t - before
        self.bar.bar_format = self._format
        self.compile = None


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


def compile_gsplat(device: str, spinner: bool = True) -> None:
    """gsplat's CUDA code built (or loaded from its cache) and run once on `device`: importing
    `gsplat.cuda._backend` is what builds it; a rasterization of three Gaussians then loads its kernels on the
    device (on the render stream, under `runtime.capture_lock`: never inside another thread's CUDA graph
    capture). Raises RenderError when gsplat found no CUDA toolkit to build with."""
    import torch

    with contextlib.nullcontext() if spinner else _no_spinner():
        from gsplat.cuda import _backend
    if _backend._C is None:
        raise RenderError(
            "gsplat found no CUDA toolkit (nvcc) to build its CUDA code with; install the CUDA toolkit "
            "(or a gsplat wheel with prebuilt kernels), or render with render.backend = 'torch'"
        )
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


def gsplat_needs_compile() -> bool:
    """True when gsplat has neither a prebuilt `gsplat.csrc` nor a cached JIT build of its CUDA
    code, so its first rasterization will compile (about a minute). Imports nothing of gsplat's."""
    import glob
    import importlib.util
    import os

    try:
        if importlib.util.find_spec("gsplat.csrc") is not None:
            return False
        from torch.utils.cpp_extension import _get_build_directory

        build = _get_build_directory("gsplat_cuda", verbose=False)
    except Exception:  # noqa: BLE001 - unknown layout: say nothing rather than mislead
        return False
    return not glob.glob(os.path.join(build, "*.so"))
