"""The per-cell result cache: OUT/cells/<id>.json, one file per finished cell, written atomically.

A file holds {"id", "params", "row"}: the cell's canonical parameters (checked on load, so a file
left by another spec or an older cell definition is ignored, never misread) and its table row,
failed or not. Writing goes to a temporary file in the same folder and is renamed over the final
name (`os.replace`, atomic on POSIX and Windows), so a rank killed mid-write leaves either the old
file or none, and concurrent ranks on a shared file system never see half a file. The cache is per
cell, not per run: any world size, any rank, and a rerun after a crash reuse every finished cell.

Reading is strict (`check_row`): a file that is not this package's JSON, a row whose status, numbers or table
columns have the wrong type, NaN or inf in a row, a cache file that is a folder, or `cells` that is a file, each
raises `OutputError` with one sentence naming the path and the fix (delete it, or `--fresh`), instead of
a traceback, or a wrong number, later in the tables. Writing never produces such a row: non-finite floats
are written as null.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Optional

from ..errors import OutputError
from ..io.config.validate import is_finite_number
from .expansion import Cell

STATUSES = ("ok", "failed")
"""The statuses a cached row may hold (`missing` rows are never written)."""
INT_KEYS = frozenset(
    {"index", "cells", "seed", "particles", "latch_frame", "fragments", "substeps", "rank", "world_size", "frames"}
)
"""Row keys the tables print as integers: an int or null."""
TEXT_KEYS = frozenset({"id", "kind", "labels", "message", "device", "device_name", "finished", "traceback", "unit"})
"""Row keys that are text."""
NUMBER_KEYS = frozenset({"cell_s", "wall_s", "dt", "error", "cfl"})
"""Row keys the driver and the tables compute with: a finite number or null."""
LOWER_BOUNDS = {
    **{k: (0, True) for k in INT_KEYS},
    **{k: (0.0, True) for k in ("cell_s", "wall_s", "error")},
    **{k: (0.0, False) for k in ("dt", "cfl")},
}
"""(bound, inclusive) of the row's counts, times and errors: a negative count or time, or a zero step, is a
damaged file, not a result."""
ACCURACY_OK_KEYS = ("dt", "particles", "substeps", "wall_s", "error", "unit")
"""Keys a finished accuracy row needs for its table row and the Pareto front."""


MAX_CACHE_BYTES = 64 * 2**20
"""The largest cache file read: a row with its traceback is a few kB; a bigger file is not the driver's."""


def cells_dir(out_dir) -> Path:
    """The folder of the cache files."""
    return Path(out_dir) / "cells"


def cache_path(out_dir, cell_id: str) -> Path:
    """Where a cell's result lives."""
    return cells_dir(out_dir) / f"{cell_id}.json"


def write_json_atomic(path: Path, payload) -> None:
    """Write JSON to `path` through a temporary file in the same folder and an atomic rename."""
    check_folder(path.parent)
    if path.is_dir():
        raise OutputError(f"{path} is a folder, not a sweep cache file; delete that folder and rerun.")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(_finite(payload), f, indent=1, default=_jsonable, allow_nan=False)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def check_folder(folder: Path) -> None:
    """The cache folder (or a folder above it) must not be a file."""
    for p in (folder, *folder.parents):
        if p.exists() and not p.is_dir():
            raise OutputError(
                f"{p} is a file, not the sweep's cache folder; move or delete it, or pass --out with another folder."
            )
        if p.exists():
            return


def _finite(value: Any) -> Any:
    """Non-finite floats → None, recursively (JSON has no NaN; a reader refuses it)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return _finite(value.tolist())
    return value


def _jsonable(o):
    """numpy / torch scalars and tensors as plain JSON values."""
    if hasattr(o, "tolist"):
        return o.tolist()
    if hasattr(o, "item"):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serializable")


def store(out_dir, cell: Cell, row: dict) -> None:
    """Cache one finished cell's row."""
    write_json_atomic(cache_path(out_dir, cell.id), {"id": cell.id, "params": cell.params, "row": row})


def load(out_dir, cell: Cell) -> Optional[dict]:
    """The cached row of `cell`, or None when there is none or the file is another cell's (another spec, an
    older cell definition). A file that cannot be this package's raises OutputError (`check_row`)."""
    path = cache_path(out_dir, cell.id)
    if path.is_dir():
        raise OutputError(
            f"{path} is a folder, not a sweep cache file; delete that folder and rerun (the cell runs again)."
        )
    if os.path.lexists(path) and path.exists() and not path.is_file():  # a FIFO would block, /dev/zero never end
        raise OutputError(
            f"{path} is not a regular file (a pipe, a device or a link to one), so it is not a sweep cache file; "
            "delete it and rerun (the cell runs again)."
        )
    if path.is_file() and path.stat().st_size > MAX_CACHE_BYTES:
        raise OutputError(
            f"{path} holds {path.stat().st_size:,} bytes, more than a sweep cache file ever does "
            f"({MAX_CACHE_BYTES // 2**20} MiB at most); delete it, or rerun with --fresh."
        )
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (an editor's) is not an error
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise OutputError(
            f"{path} cannot be read as a sweep cache file ({type(exc).__name__}); delete it, or rerun with --fresh."
        ) from None
    try:
        payload = json.loads(text)
    except ValueError:
        raise OutputError(
            f"{path} is not a sweep cache file (not JSON); delete it, or rerun with --fresh to run every cell again."
        ) from None
    except RecursionError:
        raise OutputError(
            f"{path} nests too deeply for a sweep cache file; delete it, or rerun with --fresh."
        ) from None
    if not isinstance(payload, dict) or not isinstance(payload.get("id"), str):
        raise OutputError(f"{path} is not a sweep cache file (no object with an id); delete it, or rerun with --fresh.")
    if payload.get("id") != cell.id or payload.get("params") != cell.params:
        return None
    return check_row(path, cell, payload.get("row"))


def _what(v: Any) -> str:
    if isinstance(v, bool):
        return f"the boolean {str(v).lower()}"
    if isinstance(v, (int, float)):
        return f"the number {v!r}"
    if isinstance(v, str):
        return f"the string {v[:40]!r}"
    if v is None:
        return "null"
    return "a list" if isinstance(v, list) else "an object" if isinstance(v, dict) else type(v).__name__


def _non_finite(value: Any) -> Optional[str]:
    """The path (e.g. `.latch.time` or `[3]`) of the first NaN or inf inside nested JSON, or None (iterative:
    a deeply nested file cannot exhaust the stack)."""
    todo = [("", value)]
    while todo:
        where, v = todo.pop()
        if isinstance(v, float) and not math.isfinite(v):
            return where
        if isinstance(v, dict):
            todo.extend((f"{where}.{k}", x) for k, x in v.items())
        elif isinstance(v, list):
            todo.extend((f"{where}[{i}]", x) for i, x in enumerate(v))
    return None


def check_row(path: Path, cell: Cell, row: Any) -> dict:
    """A cached row as the driver and the tables read it, or OutputError naming the file, the key and the fix."""

    def bad(key: str, problem: str) -> OutputError:
        return OutputError(
            f"{path}: the cached row's {key} {problem}; delete the file, or rerun with --fresh, to run the cell again."
        )

    if not isinstance(row, dict):
        raise bad("row", f"is {_what(row)}, not an object")
    status = row.get("status")
    if status not in STATUSES:
        raise bad("status", f"is {_what(status)}, not one of {', '.join(STATUSES)}")
    for key, v in row.items():
        if not isinstance(key, str):
            raise bad(repr(key), "is not a text key")
        if key == "extra":
            if not isinstance(v, dict):
                raise bad(key, f"is {_what(v)}, not an object")
            where = _non_finite(v)
            if where is not None:
                raise bad(f"extra{where}", "is not a finite number")
            continue
        if isinstance(v, float) and not math.isfinite(v):
            raise bad(key, f"is {v!r}, not a finite number")
        if v is None:
            continue
        if not isinstance(v, (bool, int, float, str)):
            raise bad(key, f"is {_what(v)}, not a number, text, true/false or null")
        if key in INT_KEYS and (isinstance(v, bool) or not isinstance(v, int)):
            raise bad(key, f"is {_what(v)}, not an integer")
        if key in NUMBER_KEYS and not is_finite_number(v):
            raise bad(key, f"is {_what(v)[:60]}, not a number")  # a 400-digit integer is shown by its start
        if isinstance(v, (int, float)) and not isinstance(v, bool) and not is_finite_number(v):
            raise bad(key, f"is {_what(v)[:60]}, too large for a number")
        low = LOWER_BOUNDS.get(key)
        if low is not None and not isinstance(v, str) and (v < low[0] or (not low[1] and v == low[0])):
            raise bad(key, f"is {v!r}, not {'at least' if low[1] else 'above'} {low[0]:g} (no run writes that)")
        if key in TEXT_KEYS and not isinstance(v, str):
            raise bad(key, f"is {_what(v)}, not text")
    if status == "ok" and cell.kind == "accuracy":
        for key in ACCURACY_OK_KEYS:
            if row.get(key) is None:
                raise bad(key, "is missing from a finished accuracy cell")
        for key in ("particles", "substeps"):
            if row[key] < 1:
                raise bad(key, f"is {row[key]}, but a finished accuracy cell simulated at least one")
    return row


def scan(out_dir, cells: list[Cell], device_type: str) -> dict[str, dict]:
    """{id: row} of the cells cached in `out_dir` by a run on the same device type (cpu or cuda): a
    CPU result is not reused by a GPU run (its wall time would mix into the GPU's speed-vs-error)."""
    found = {}
    folder = cells_dir(out_dir)
    check_folder(folder)
    if not folder.is_dir():
        return found
    for cell in cells:
        row = lookup(out_dir, cell, device_type)
        if row is not None:
            found[cell.id] = row
    return found


def lookup(out_dir, cell: Cell, device_type: str) -> Optional[dict]:
    """`cell`'s cached row when a run on `device_type` (cpu or cuda) wrote it, else None (see `scan`)."""
    row = load(out_dir, cell)
    if row is not None and str(row.get("device", "cpu")).split(":")[0] == device_type:
        return row
    return None
