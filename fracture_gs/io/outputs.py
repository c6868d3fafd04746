"""Output folders and files checked before any work: one sentence (OutputError) naming the path, the
problem and the fix, instead of the OSError traceback that `mkdir` or `open` would give an hour later."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import OutputError


def _blocking_file(path: Path) -> Path | None:
    """The first existing non-directory on the way to `path` (itself included), if any."""
    for p in [*reversed(path.parents), path]:
        if p.exists() and not p.is_dir():
            return p
    return None


def _unusable(path: Path, flag: str, err: OSError) -> OutputError:
    """A path the system refuses to look at (a name over 255 bytes, a path over 4096, a loop of links)."""
    reason = err.strerror or type(err).__name__
    return OutputError(f"{flag} {path} cannot be used as a path ({reason}); choose a shorter or plainer path.")


def output_dir(path, flag: str = "--out") -> Path:
    """Create (if needed) and return a writable output folder, or raise OutputError."""
    if not os.fspath(path).strip():
        raise OutputError(f"{flag} is empty; give a folder for the outputs, e.g. {flag} runs/mine.")
    path = Path(path)
    try:
        blocker = _blocking_file(path)
    except OSError as err:
        raise _unusable(path, flag, err) from None
    if blocker == path:
        raise OutputError(f"{flag} {path} is a file, not a folder; choose a folder path or remove the file.")
    if blocker is not None:
        raise OutputError(
            f"{flag} {path} lies under the file {blocker}; choose a folder path that is not inside a file."
        )
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(
            f"{flag} {path} cannot be created ({err.strerror or type(err).__name__}); choose a folder you can write to."
        ) from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(f"{flag} {path} is not writable; choose a folder you can write to.")
    return path


def output_file(path, flag: str = "--out") -> Path:
    """Check that a file can be written at `path` (its folder is created); return the path."""
    if not os.fspath(path).strip():
        raise OutputError(f"{flag} is empty; give a file name, e.g. {flag} scene.toml.")
    path = Path(path)
    try:
        path.exists()
    except OSError as err:
        raise _unusable(path, flag, err) from None
    if path.is_dir():
        raise OutputError(f"{flag} {path} is a folder; give a file name, e.g. {flag} {path / 'scene.toml'}.")
    if path.exists() and not path.is_file():
        raise OutputError(f"{flag} {path} is not a regular file; choose a file path such as scene.toml.")
    output_dir(path.parent if str(path.parent) else Path("."), flag=f"the folder of {flag} {path}")
    return path


def check_output_paths(out_dir: Path, files=(), folders=(), flag: str = "--out") -> None:
    """Before the work: none of the `files` a command writes in `out_dir` is a folder (or a pipe, a device), and
    none of the `folders` it fills is a file, so the run does not end in an OSError traceback, or with an output
    silently missing, after its work is done."""
    for name in files:
        p = Path(out_dir) / name
        if p.exists() and not p.is_file():
            what = "a folder" if p.is_dir() else "not a regular file"
            raise OutputError(
                f"{flag} {out_dir} holds {what} named {name}, where the run writes its {name} file; remove it or "
                f"choose another {flag}."
            )
    for name in folders:
        p = Path(out_dir) / name
        if p.exists() and not p.is_dir():
            raise OutputError(
                f"{flag} {out_dir} holds a file named {name}, where the run writes its {name}/ folder; remove it or "
                f"choose another {flag}."
            )
