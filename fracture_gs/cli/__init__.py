"""`fracture-gs` command line: render-sim, init, bench, figures, sweep, view, info, validate.

Every user error (bad config, bad PLY, missing file, bad flag) ends as one line
`fracture-gs: error: <sentence>` on stderr and exit code 2, never a traceback (set
FRACTURE_GS_DEBUG=1 to get the traceback instead). A flag that would do nothing in the combination
given is such an error too (`run.refuse_ignored_flags`). The heavy work lives
in modules imported only when a command needs them (`fracture_gs.render_sim`, `fracture_gs.paper`), so
`--help`, `info` and `validate` stay fast and work on any machine.

This module imports nothing heavy at its top: the parser and the commands (torch, Warp) are imported
inside `main`'s handler, so Ctrl-C at any moment, the first second of imports included, exits 130
with one line.
"""

import os
import sys

TYPE_CHECKING = False  # typing is not imported at the top: see the module doc
if TYPE_CHECKING:
    from typing import Optional, Sequence

PROG = "fracture-gs"


class CliError(Exception):
    """A user-facing error: its message is one sentence, printed without a traceback."""


__all__ = ["CliError", "PROG", "build_parser", "main", "resolve_device"]

_WARP_COMMANDS = ("render-sim", "bench", "figures", "sweep")
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


def main(argv: "Optional[Sequence[str]]" = None) -> int:
    """Console entry point; returns the exit code (0 ok, 2 user error, 130 interrupted). Everything that can
    take time, the imports of torch and Warp included, runs inside the KeyboardInterrupt handler."""
    args = None
    argv_was_none = argv is None  # the process itself (console script, python -m): it exits when main returns
    interrupts = _Interrupts()
    try:
        interrupts.install()
        from .devices import _prepare_warp
        from .parser import build_parser

        parser = build_parser()
        argv = list(argv) if argv is not None else sys.argv[1:]
        args = parser.parse_args(argv)
        args.argv = argv  # what was typed, for the commands that record it
        if not args.command:
            parser.print_help()
            return 0
        commands = _commands()
        interrupts.check()
        # a run's buffers change size every frame (fragments, boxes, visible Gaussians): expandable segments keep
        # torch's CUDA cache near what is allocated (a 150k-Gaussian capture held 69 GiB reserved for 17 in use)
        os.environ.setdefault("PYTORCH_CUDA_ALLOC_CONF", "expandable_segments:True")
        if args.command in _WARP_COMMANDS:
            _prepare_warp()
        interrupts.check()
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
        interrupts.restore(leaving=argv_was_none)


def _interrupted(args) -> int:
    partial = getattr(args, "partial_out", None)  # set by a command once it knows its output folder
    where = f"partial outputs are in {partial}" if partial else "nothing was written"
    print(f"\n{PROG}: interrupted; {where}.", file=sys.stderr)
    return 130
