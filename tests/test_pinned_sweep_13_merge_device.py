"""Pinned rule of a sweep that lost a rank (`sweep.driver._merge`), round thirteen: the dead rank's finished cells are
looked up in the shared cache by the device *type* of the run (``cuda`` for ``cuda:1``, ``cpu`` for ``cpu``), the
same key every cached row is written under, never by the device index; cells neither gathered nor cached become
``missing`` rows that name the stopped rank.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from fracture_gs.sweep import cache, driver
from fracture_gs.sweep.expansion import Cell


def cell(i: int) -> Cell:
    return Cell(i, f"{i:012x}", "scene", {"kind": "scene"}, {}, ("t",))


@pytest.mark.parametrize("device, kind", [("cuda:1", "cuda"), ("cuda:0", "cuda"), ("cpu", "cpu")])
def test_a_dead_ranks_cells_are_read_from_the_cache_by_device_type(tmp_path, monkeypatch, device, kind):
    """With rank 1 stopped, the cells no rank returned are asked of the cache with the device type, and a cached
    row found there fills its cell."""
    asked = []

    def scan(out, cells, device_type):
        asked.append((out, [c.id for c in cells], device_type))
        return {cells[0].id: {"status": "ok", "note": "from the cache"}}

    monkeypatch.setattr(cache, "scan", scan)
    cells = [cell(0), cell(1), cell(2)]
    gathered = [{cells[0].id: {"status": "ok", "note": "from rank 0"}}]
    rows = driver._merge(tmp_path, device, cells, {}, gathered, SimpleNamespace(rank=1))
    assert asked == [(tmp_path, [cells[1].id, cells[2].id], kind)]
    assert [r.get("note") for r in rows] == ["from rank 0", "from the cache", None]
    assert rows[2]["status"] == "missing" and "rank 1 stopped" in rows[2]["message"]


def test_without_a_failure_the_cache_is_not_scanned(tmp_path, monkeypatch):
    """When every rank finished, the merge reads nothing from the disk: a cell no rank ran is `missing`."""
    monkeypatch.setattr(cache, "scan", lambda *a: pytest.fail("scanned the cache"))
    rows = driver._merge(tmp_path, "cpu", [cell(0)], {}, [], None)
    assert rows[0]["status"] == "missing" and "no rank ran it" in rows[0]["message"]
