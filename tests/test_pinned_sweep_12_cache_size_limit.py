"""The sweep cache's reader (`fracture_gs.sweep.cache.load`) refuses a file larger than `MAX_CACHE_BYTES`
(64 MiB, documented on the constant) before reading it: a row with its traceback is a few kB, so a bigger file is
not the driver's, and reading it whole could exhaust memory. The limit is inclusive: a file of exactly the limit
is read (and judged on its content), one byte more is refused with one sentence naming the path, the size with
thousands separators, the limit in MiB and the fix. Sparse files stand in for the big ones (no disk is used).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fracture_gs.errors import OutputError
from fracture_gs.sweep import cache
from fracture_gs.sweep.expansion import Cell

CELL = Cell(0, "0123456789ab", "scene", {"kind": "scene"}, {"kind": "scene"}, ("t",))
ROW = {"status": "ok", "message": "", "frames": 3}


def cache_file(tmp_path) -> Path:
    path = cache.cache_path(tmp_path, CELL.id)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def sparse(path, size: int) -> None:
    """A file of `size` bytes (all zero) that takes no disk space."""
    with open(path, "wb") as f:
        f.truncate(size)
    assert path.stat().st_size == size


def padded(path, size: int) -> None:
    """A valid cache file of this cell, padded with trailing JSON whitespace to exactly `size` bytes."""
    text = json.dumps({"id": CELL.id, "params": CELL.params, "row": ROW})
    assert len(text) < size
    path.write_text(text + " " * (size - len(text)), encoding="utf-8")
    assert path.stat().st_size == size


def test_the_documented_limit_is_sixty_four_mib():
    """The constant is 64 MiB = 67,108,864 bytes, as its docstring and the refusal message say."""
    assert cache.MAX_CACHE_BYTES == 67_108_864 == 64 * 1024 * 1024


def test_one_byte_over_sixty_four_mib_is_refused_naming_size_and_limit(tmp_path):
    """A 64 MiB + 1 byte file is refused before it is read: the message names the path, its size as
    67,108,865 bytes and the limit as 64 MiB (not 63, not 128), and the fix."""
    path = cache_file(tmp_path)
    sparse(path, 64 * 2**20 + 1)
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, CELL)
    assert str(info.value) == (
        f"{path} holds 67,108,865 bytes, more than a sweep cache file ever does (64 MiB at most); "
        "delete it, or rerun with --fresh."
    )


def test_exactly_sixty_four_mib_is_read_not_refused_for_its_size(tmp_path):
    """A file of exactly 64 MiB is within the limit: it is read, and refused only for what it holds (zero
    bytes are not JSON) — the size refusal starts one byte later."""
    path = cache_file(tmp_path)
    sparse(path, 64 * 2**20)
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, CELL)
    assert str(info.value) == (
        f"{path} is not a sweep cache file (not JSON); delete it, or rerun with --fresh to run every cell again."
    )


@pytest.mark.parametrize(
    ("limit", "shown_size", "shown_mib"), [(2**20 + 1000, "1,049,577", "1"), (3 * 2**20 - 1, "3,145,728", "2")]
)
def test_the_limit_is_inclusive_at_the_byte(tmp_path, monkeypatch, limit, shown_size, shown_mib):
    """With the limit set to L bytes: a valid file of L - 1 or L bytes loads and gives its row back unchanged;
    L + 1 bytes is refused, the message giving the size with thousands separators and the limit in whole MiB
    (rounded down: L // 2**20)."""
    monkeypatch.setattr(cache, "MAX_CACHE_BYTES", limit)
    path = cache_file(tmp_path)
    for size in (limit - 1, limit):
        padded(path, size)
        assert cache.load(tmp_path, CELL) == ROW, size
    padded(path, limit + 1)
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, CELL)
    assert str(info.value) == (
        f"{path} holds {shown_size} bytes, more than a sweep cache file ever does ({shown_mib} MiB at most); "
        "delete it, or rerun with --fresh."
    )


def test_a_missing_file_is_no_row_not_a_size_error(tmp_path, monkeypatch):
    """No file: load returns None (the cell runs), whatever the limit (the size check only looks at files)."""
    monkeypatch.setattr(cache, "MAX_CACHE_BYTES", 0)
    cache_file(tmp_path)
    assert cache.load(tmp_path, CELL) is None
