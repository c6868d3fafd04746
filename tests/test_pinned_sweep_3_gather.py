"""Pinned rules of a sweep over several ranks as one rank sees it (`fracture_gs.sweep.driver.run_sweep`, `_merge`,
`_sigterm_note`): a rank other than 0 runs the cells the plan gives it and hands them, with the cached rows it
holds, to rank 0; ranks that expanded the spec differently stop; a SIGTERM says what is kept; rank 0 merges every
row in cell order and marks what nobody ran as `missing`, saying why.

Unit-level calls only: the coordinator is a fake (no process group) and no cell runs (`run_one` is replaced).
"""

from __future__ import annotations

import signal

import pytest

from fracture_gs.sweep import cache, driver
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.expansion import expand
from fracture_gs.sweep.spec import load_spec

SPEC = '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16, 32, 48, 64]\ncfl = 0.4\n'
DONE = {"dt": 1e-4, "particles": 8, "substeps": 10, "wall_s": 1.0, "error": 0.25, "unit": "%"}


class FakeCoordinator:
    """Plans with the real make_plan over (rank 0: nothing cached, rank 1: this rank's cache), or returns `plan`;
    records the rows handed over and the SIGTERM handler in place at that moment."""

    def __init__(self, plan=None):
        self.given_plan, self.handed, self.handler = plan, None, None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def plan(self, cached, make_plan):
        return self.given_plan or make_plan([{}, cached])

    def finish(self, rows):
        self.handed, self.handler = rows, signal.getsignal(signal.SIGTERM)
        return None


@pytest.fixture
def rank_one(tmp_path, monkeypatch):
    """Rank 1 of 2 on the CPU with a four-cell spec, cell 1/16 already in its cache; run_one is a fake."""
    (tmp_path / "s.toml").write_text(SPEC)
    cells = expand(load_spec(tmp_path / "s.toml"))
    out = tmp_path / "out"
    cache.store(out, cells[0], {**driver.base_row(cells[0]), "status": "ok", "device": "cpu", **DONE})
    monkeypatch.setattr(driver, "launch_from_env", lambda: D.Launch(1, 2, 1, 2, "h:1"))
    monkeypatch.setattr(driver, "resolve_device", lambda flag, launch: "cpu")
    monkeypatch.setattr(driver, "warmup", lambda device: None)
    ran = []

    def run_one(cell, launch, device, out_dir):
        ran.append(cell.index)
        return {**driver.base_row(cell), "status": "ok", "cell_s": 0.5, "device": device, **DONE}

    monkeypatch.setattr(driver, "run_one", run_one)
    return tmp_path / "s.toml", out, cells, ran


def test_a_rank_runs_its_share_and_hands_it_with_its_cached_rows_to_rank_zero(rank_one, monkeypatch):
    """Rank 1 runs the cells the plan deals it (1/32 and 1/48: the costliest, 1/64, went to rank 0), caches each,
    prints one line per cell (after the warm-up), hands rank 0 those rows plus the cached row only it holds, and
    reports what it ran without any table (rank 0 writes those)."""
    spec, out, cells, ran = rank_one
    coord = FakeCoordinator()
    monkeypatch.setattr(driver, "coordinator", lambda launch, device, timeout, beat: coord)
    lines = []
    report = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lines.append))
    assert ran == [1, 2]
    assert sorted(coord.handed) == sorted(c.id for c in cells[:3])
    assert coord.handed[cells[0].id]["wall_s"] == 1.0 and coord.handed[cells[2].id]["cell_s"] == 0.5
    assert cache.load(out, cells[2])["status"] == "ok"
    assert (report.rank, report.world_size, report.cells, report.ran, report.rows, report.files) == (1, 2, 4, 2, [], [])
    assert lines[0] == f"[rank 1/2] cpu (no process group): 2 of 4 cells to run here, 1 cached in {out / 'cells'}"
    assert lines[1].startswith("[rank 1/2] warm-up (kernels compiled and loaded) ")
    assert lines[2] == f"[rank 1/2] 1/2 cell 2/4 {cells[1].id} bar Δx=1/32 CFL 0.4: ok 0.5 s, error 2.500e-01 (%)"
    assert lines[3].startswith(f"[rank 1/2] 2/2 cell 3/4 {cells[2].id} bar Δx=1/48")
    assert lines[-1] == "[rank 1/2] done: 2 cell(s) run, results handed to rank 0"


def test_a_sigterm_while_ranks_work_says_how_many_cells_are_kept(rank_one, monkeypatch, capsys):
    """While a distributed sweep runs, SIGTERM (torchrun stopping every rank when one fails) prints which rank
    stopped, how many cells it finished and where they are cached, and exits 128 + the signal; the previous
    handler is back once the sweep returns."""
    spec, out, cells, ran = rank_one
    coord = FakeCoordinator()
    monkeypatch.setattr(driver, "coordinator", lambda launch, device, timeout, beat: coord)
    before = signal.getsignal(signal.SIGTERM)
    driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lambda s: None))
    assert signal.getsignal(signal.SIGTERM) is before and coord.handler is not before
    codes = []
    monkeypatch.setattr(driver.os, "_exit", codes.append)
    coord.handler(signal.SIGTERM, None)
    assert codes == [128 + signal.SIGTERM]
    err = capsys.readouterr().err
    assert err == (
        f"[rank 1/2] stopped by signal {int(signal.SIGTERM)} (torchrun stops every rank when one fails); the 2 "
        f"cell(s) this rank finished are cached in {out / 'cells'}; rerun the same command to resume.\n"
    )


def test_ranks_that_expanded_the_spec_differently_stop(rank_one, monkeypatch):
    """A plan made from another cell list (its digest differs) stops the rank with a LaunchError naming the spec
    and the fix, before any cell runs; the SIGTERM handler is restored."""
    spec, out, cells, ran = rank_one
    coord = FakeCoordinator({"digest": "0" * 16, "assign": [[], [1]], "send": [[], []], "cached": 0})
    monkeypatch.setattr(driver, "coordinator", lambda launch, device, timeout, beat: coord)
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(D.LaunchError, match=r"^\[rank 1/2\] expanded .*s\.toml to other cells than rank 0 did; every"):
        driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lambda s: None))
    assert ran == [] and signal.getsignal(signal.SIGTERM) is before


# ---------------------------------------------------------------------------------------------
# rank 0's merge


def test_rank_zero_merges_rows_in_cell_order_and_says_why_one_is_missing(tmp_path):
    """Rank 0's rows: one per cell in cell order, a gathered row before its own cached one, the cell's own
    parameters over the row's; a cell nobody ran is `missing` saying so — with a dead rank, naming it, after
    looking for that cell on this disk (a shared folder may hold what the dead rank finished)."""
    (tmp_path / "s.toml").write_text(SPEC)
    a, b, c, d = expand(load_spec(tmp_path / "s.toml"))
    out = tmp_path / "out"
    found = {a.id: {"status": "ok", "error": 1.0}, b.id: {"status": "failed", "message": "old"}}
    gathered = [{b.id: {"status": "ok", "error": 2.0, "index": 99}}, {c.id: {"status": "ok", "error": 3.0}}]
    rows = driver._merge(out, "cpu", [a, b, c, d], found, gathered, None)
    assert [(r["index"], r["id"], r["status"], r.get("error")) for r in rows] == [
        (0, a.id, "ok", 1.0),
        (1, b.id, "ok", 2.0),
        (2, c.id, "ok", 3.0),
        (3, d.id, "missing", None),
    ]
    assert rows[3]["message"] == "not run (no rank ran it); rerun the sweep to resume"
    assert rows[1]["labels"] == "dx" and rows[1]["cells"] == 32
    cache.store(out, c, {"status": "ok", "device": "cpu", **DONE})
    failure = D.RankFailure("rank 1 of 2 sent no heartbeat", 1)
    rows = driver._merge(out, "cpu", [a, b, c, d], found, [{}], failure)
    assert [r["status"] for r in rows] == ["ok", "failed", "ok", "missing"]
    assert rows[2]["error"] == 0.25
    assert rows[3]["message"] == "not run (rank 1 stopped); rerun the sweep to resume"
