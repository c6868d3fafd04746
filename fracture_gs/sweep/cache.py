"""The per-cell result cache: OUT/cells/<id>.json, one file per finished cell, written atomically.

A file holds {"id", "params", "row"}: the cell's canonical parameters (checked on load, so a file
left by another spec or an older cell definition is ignored, never misread) and its table row,
failed or not. Writing goes to a temporary file in the same folder and is renamed over the final
name (`os.replace`, atomic on POSIX and Windows), so a rank killed mid-write leaves either the old
file or none, and concurrent ranks on a shared file system never see half a file. The cache is per
cell, not per run: any world size, any rank, and a rerun after a crash reuse every finished cell.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Optional

from .expansion import Cell


def cells_dir(out_dir) -> Path:
    """The folder of the cache files."""
    return Path(out_dir) / "cells"


def cache_path(out_dir, cell_id: str) -> Path:
    """Where a cell's result lives."""
    return cells_dir(out_dir) / f"{cell_id}.json"


def write_json_atomic(path: Path, payload) -> None:
    """Write JSON to `path` through a temporary file in the same folder and an atomic rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(payload, f, indent=1, default=_jsonable)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


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
    """The cached row of `cell`, or None when there is none or the file is not this cell's."""
    path = cache_path(out_dir, cell.id)
    try:
        payload = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(payload, dict) or payload.get("id") != cell.id or payload.get("params") != cell.params:
        return None
    row = payload.get("row")
    return row if isinstance(row, dict) else None


def scan(out_dir, cells: list[Cell], device_type: str) -> dict[str, dict]:
    """{id: row} of the cells cached in `out_dir` by a run on the same device type (cpu or cuda): a
    CPU result is not reused by a GPU run (its wall time would mix into the GPU's speed-vs-error)."""
    found = {}
    if not cells_dir(out_dir).is_dir():
        return found
    for cell in cells:
        row = load(out_dir, cell)
        if row is not None and str(row.get("device", "cpu")).split(":")[0] == device_type:
            found[cell.id] = row
    return found
