"""`fracture-gs` command line: render-sim, init, bench, figures, sweep, view, info, validate.

Every user error (bad config, bad PLY, missing file, bad flag) ends as one line
`fracture-gs: error: <sentence>` on stderr and exit code 2, never a traceback (set
FRACTURE_GS_DEBUG=1 to get the traceback instead). A flag that would do nothing in the combination
given is such an error too (`run.refuse_ignored_flags`). The heavy work lives
in modules imported only when a command needs them (`fracture_gs.render_sim`, `fracture_gs.paper`), so
`--help`, `info` and `validate` stay fast and work on any machine.

This module imports nothing heavy at its top: the parser and the commands are imported inside `main`'s
handler, so Ctrl-C at any moment, the first second of imports included, exits 130 with one line. The
parser, `info`, `validate` and every flag check import neither torch nor Warp nor gsplat: a command
imports them (and prepares Warp, `devices._prepare_warp`) once its flags and config are checked.
"""

import os
import sys
import time

TYPE_CHECKING = False  # typing is not imported at the top: see the module doc
if TYPE_CHECKING:
    from typing import Optional, Sequence

PROG = "fracture-gs"


class CliError(Exception):
    """A user-facing error: its message is one sentence, printed without a traceback."""


__all__ = ["CliError", "PROG", "build_parser", "finish", "main", "resolve_device", "run"]

_LAZY = {"build_parser": "parser", "resolve_device": "devices"}
_SUBMODULES = ("devices", "parser", "report", "run", "sweep", "view")


def __getattr__(name: str) -> object:
    """`cli.resolve_device`, `cli.CliError`, `cli.build_parser` and the submodules, imported on first use."""
    import importlib

    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _commands() -> dict:
    """Command name -> function (imports the command modules)."""
    from .report import cmd_info, cmd_validate
    from .run import cmd_bench, cmd_figures, cmd_init, cmd_render_sim
    from .sweep import cmd_sweep
    from .view import cmd_view

    return {
        "render-sim": cmd_render_sim,
        "bench": cmd_bench,
        "figures": cmd_figures,
        "info": cmd_info,
        "validate": cmd_validate,
        "init": cmd_init,
        "sweep": cmd_sweep,
        "view": cmd_view,
    }


# --------------------------------------------------------------------------------------------
# entry point


def _user_error_types() -> tuple[type, ...]:
    """Exceptions reported as one line: flags, config, PLY, scene, output folder, missing files, bad values."""
    from ..errors import ConfigError, FractureGSError, OutputError, PlyError, SceneError  # errors.py imports nothing

    return (CliError, ConfigError, PlyError, SceneError, OutputError, FractureGSError, FileNotFoundError)


def _one_line(exc: BaseException) -> str:
    """The error as one line (FileNotFoundError gets its path)."""
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file or directory; check the path."
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text


class _Interrupts:
    """SIGINT while main() runs: raises KeyboardInterrupt as usual and also sets `hit`, so an interrupt that
    Python drops (raised inside a finalizer or an import lock's callback, printed as "Exception ignored") still
    ends the command with 130 at its next check. Only in the main thread, and not where SIGINT is ignored (a
    background job of a non-interactive shell) or handled by someone else (an embedding application)."""

    def __init__(self) -> None:
        self.hit = False
        self.previous = None
        self.held = 0  # > 0 inside `held_interrupts()`: a SIGINT is recorded, raised on leaving

    def __enter__(self) -> "_Interrupts":
        self.held += 1
        return self

    def __exit__(self, *exc) -> None:
        self.held -= 1
        if not self.held and exc[0] is None:  # an exception already leaving the block goes on as it is
            self.check()

    def install(self) -> None:
        import signal
        import threading

        if threading.current_thread() is not threading.main_thread():
            return
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            return
        self.previous = signal.signal(signal.SIGINT, self._handler)

    def _handler(self, signum, frame) -> None:
        self.hit = True
        if not self.held and not in_finalizer(frame):  # in a finalizer, `check` raises it at the next check
            raise KeyboardInterrupt

    def check(self) -> None:
        """Raise the KeyboardInterrupt that was dropped, if one was."""
        if self.hit:
            raise KeyboardInterrupt

    def restore(self, leaving: bool = False) -> None:
        """Put the previous handler back; `leaving` (main() runs as the program, which exits next): ignore SIGINT
        instead, so a Ctrl-C during the interpreter's shutdown neither prints a traceback nor kills the process
        by the signal (exit -2) after the command has already ended with its code."""
        if self.previous is not None:
            import signal

            signal.signal(signal.SIGINT, signal.SIG_IGN if leaving else self.previous)
            self.previous = None


def in_finalizer(frame) -> bool:
    """Whether a signal handler interrupted a finalizer (`__del__`, up the stack of `frame`): a KeyboardInterrupt
    raised there is printed as "Exception ignored in ..." with its traceback and dropped, so a handler only records
    the Ctrl-C then (the command stops at its next check and exits 130 with its one line)."""
    while frame is not None:
        if frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


_running: "Optional[_Interrupts]" = None  # main()'s, while it runs


def interrupt_handled() -> None:
    """A command whose normal end is Ctrl-C (`view` serves until then) says it handled the interrupt, so main()
    returns the command's own code instead of turning the recorded Ctrl-C into 130 and "interrupted"."""
    if _running is not None:
        _running.hit = False


def held_interrupts():
    """A context in which Ctrl-C is recorded rather than raised, and raised as KeyboardInterrupt when it ends:
    for `import torch`, whose C++ start-up calls back into Python, so a KeyboardInterrupt raised there ends the
    process with std::terminate (exit -6) instead of 130. Ctrl-C then takes effect once torch has loaded.
    Outside main() (the package used as a library) or its thread it holds nothing back."""
    import threading

    if _running is None or threading.current_thread() is not threading.main_thread():
        import contextlib

        return contextlib.nullcontext()
    return _running


def main(argv: "Optional[Sequence[str]]" = None) -> int:
    """Console entry point; returns the exit code (0 ok, 2 user error, 130 interrupted). Everything that can
    take time, the imports of torch and Warp included, runs inside the KeyboardInterrupt handler."""
    entered = time.perf_counter()
    args = None
    argv_was_none = argv is None  # the process itself (console script, python -m): it exits when main returns
    global _running
    interrupts, outer = _Interrupts(), _running
    try:
        interrupts.install()
        _running = interrupts
        from .parser import build_parser

        parser = build_parser()
        argv = list(argv) if argv is not None else sys.argv[1:]
        args = parser.parse_args(argv)
        from .ignored import refuse_repeated

        refuse_repeated(parser, argv)  # a flag typed twice with different values: the first would do nothing
        args.argv = argv  # what was typed, for the commands that record it
        args.entered, args.is_process = entered, argv_was_none  # for --profile's start-up rows
        if not args.command:
            parser.print_help()
            return 0
        commands = _commands()
        interrupts.check()
        # a run's buffers change size every frame (fragments, boxes, visible Gaussians): expandable segments keep
        # torch's CUDA cache near what is allocated (a 150k-Gaussian capture held 69 GiB reserved for 17 in use)
        os.environ.setdefault("PYTORCH_CUDA_ALLOC_CONF", "expandable_segments:True")
        code = commands[args.command](args)
        interrupts.check()
        return code
    except SystemExit as exc:  # --help / --version: keep main() returning an exit code
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    except KeyboardInterrupt:
        return _interrupted(args)
    except Exception as exc:  # noqa: BLE001 - user errors become one line, bugs keep their traceback
        if interrupts.hit:  # e.g. a C extension's import turned the KeyboardInterrupt into an ImportError
            return _interrupted(args)
        if os.environ.get("FRACTURE_GS_DEBUG"):
            raise
        if isinstance(exc, _user_error_types()):
            print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
            return 2
        if isinstance(exc, ValueError):  # not ours: every bad input is refused as a package error where it enters
            print(
                f"{PROG}: internal error: {type(exc).__name__}: {_one_line(exc)}; this is a bug in {PROG}, "
                f"not in your input: rerun with FRACTURE_GS_DEBUG=1 for the traceback and report it.",
                file=sys.stderr,
            )
            return 1
        raise
    finally:
        _running = outer
        interrupts.restore(leaving=argv_was_none)


def _interrupted(args) -> int:
    # CPython records a KeyboardInterrupt that escapes code run from a string (`eval("...")`: inspect evaluates
    # string annotations that way, which Warp does as it imports) and, for `python -m`, kills the process by
    # SIGINT at exit although this handler caught it; the next string it runs clears that record, so run one.
    eval("None")
    partial = getattr(args, "partial_out", None)  # set by a command once it knows its output folder
    where = f"partial outputs are in {partial}" if partial and _holds_anything(partial) else "nothing was written"
    print(f"\n{PROG}: interrupted; {where}.", file=sys.stderr)
    return 130


def _holds_anything(folder) -> bool:
    """Whether the output folder has any entry (a Ctrl-C before the first file is written leaves it empty, and
    "partial outputs are in" an empty folder would send the user to look for nothing)."""
    try:
        with os.scandir(folder) as entries:
            return any(True for _ in entries)
    except OSError:
        return False


def run() -> None:
    """The `fracture-gs` program (console script and `python -m fracture_gs.cli`): `main()`, then `finish`."""
    finish(main())


def finish(code: int) -> None:
    """End the process with `code`. Once torch is loaded, the interpreter's own teardown (finalising torch's and
    Warp's modules and objects) took 0.65 s after a CPU run's last line (2026-11-29), work whose result nobody
    reads. So, as Python itself would at exit, wait for the threads that are not daemons (`threading._shutdown`,
    which also ends idle executor workers) and run the atexit handlers (forked workers joined, finalizers of
    temporary files, logging flushed), flush stdout and stderr, then leave without the teardown (`os._exit`).
    Outputs are closed by then: every writer of a run is closed before `main` returns. Without torch loaded
    (`--help`, `info`, errors before a run) or where those hooks are missing, a plain exit."""
    import atexit
    import threading

    shutdown, run_exitfuncs = getattr(threading, "_shutdown", None), getattr(atexit, "_run_exitfuncs", None)
    if "torch" not in sys.modules or shutdown is None or run_exitfuncs is None:
        sys.exit(code)
    shutdown()
    run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):  # closed or replaced by the caller
            pass
    os._exit(code)
