"""A cell's row (`fracture_gs.sweep.driver.run_one`) holds exactly: the cell's parameters (index, id, kind, labels,
its info), the flat metrics, status and message, where and how long it ran; the non-flat results (`extra`, e.g.
the latch record, the fragment sizes) only when the cell produced some, so that they reach the cache file and
come back from it, and a cell without them carries no empty `extra` table. A failed outcome keeps its extra too.

Unit-level calls only: `run_cell` is replaced, no simulation runs.
"""

from __future__ import annotations

import pytest

from fracture_gs.sweep import cache, driver
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.cells import Outcome
from fracture_gs.sweep.expansion import Cell

EXTRA = {"latch": {"latch_frame": 4, "latch_time": 0.04}, "fragments": [3, 1]}
RAN = {"cell_s", "rank", "world_size", "device", "device_name", "finished"}


def cell() -> Cell:
    info = {"config": "bread", "variant": "full", "seed": 0}
    return Cell(7, "00000000000a", "scene", {"kind": "scene", "i": 7}, info, ("a", "b"))


def row_of(monkeypatch, outcome: Outcome) -> dict:
    monkeypatch.setattr(driver, "run_cell", lambda c, dev, out: outcome)
    launch = D.Launch(rank=1, world_size=2, local_rank=1, local_world_size=2, master="h:1")
    return driver.run_one(cell(), launch, "cpu", None)


def test_a_row_without_extra_results_has_no_extra_key(monkeypatch):
    """An ok outcome with no extra gives a row of the cell's parameters, its metrics, status ok, an empty
    message and where it ran: no `extra` key (an empty table would be written into every cache file)."""
    row = row_of(monkeypatch, Outcome({"opening": 1.5, "particles": 321}))
    made = {"index", "id", "kind", "labels", "config", "variant", "seed", "opening", "particles", "status", "message"}
    assert set(row) == made | RAN
    assert (row["index"], row["id"], row["kind"], row["labels"]) == (7, "00000000000a", "scene", "a+b")
    assert (row["opening"], row["particles"], row["status"], row["message"]) == (1.5, 321, "ok", "")
    assert (row["rank"], row["world_size"], row["device"]) == (1, 2, "cpu")


@pytest.mark.parametrize("status", ["ok", "diverged at frame 9: x"])
def test_extra_results_go_into_the_row_and_come_back_from_the_cache(monkeypatch, tmp_path, status):
    """An outcome with extra results (finished or stopped early) puts them in the row's `extra`, unchanged; the
    row stored in the cache file reads back with the same extra (the reader checks it is an object of finite
    numbers)."""
    row = row_of(monkeypatch, Outcome({"opening": 1.5}, status, dict(EXTRA)))
    assert row["extra"] == EXTRA
    assert (row["status"], row["message"]) == (("ok", "") if status == "ok" else ("failed", status))
    cache.store(tmp_path, cell(), row)
    back = cache.load(tmp_path, cell())
    assert back["extra"] == EXTRA and back["opening"] == 1.5 and back["status"] == row["status"]


def test_a_failed_outcome_without_extra_has_no_extra_key(monkeypatch):
    """A cell stopped early with no extra results: failed, the reason as message, no `extra`."""
    row = row_of(monkeypatch, Outcome({}, "diverged at frame 2: NaN"))
    assert (row["status"], row["message"]) == ("failed", "diverged at frame 2: NaN")
    assert "extra" not in row and "traceback" not in row
