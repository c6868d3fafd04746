"""Pinned rules of the sweep driver's listing and progress lines (`fracture_gs.sweep.driver`): `--list` under
several ranks shows every cell with its cache status and the rank the cost-balanced plan gives it, a cache
written on another device type does not count, and a finished cell's progress line shows its status, seconds
and headline numbers.

Unit-level calls only: no cell runs (the cache files are written by hand, the listing never runs anything).
"""

from __future__ import annotations

import pytest

from fracture_gs.sweep import cache, driver
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.expansion import expand
from fracture_gs.sweep.spec import load_spec

SPEC = '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16, 32, 48, 64]\ncfl = 0.4\n'


@pytest.fixture
def four(tmp_path):
    """A spec of four bar cells (Δx = 1/16 .. 1/64; a finer grid costs more), 1/16 cached ok and 1/32 cached
    failed by a CPU run, 1/48 cached by a GPU run."""
    (tmp_path / "s.toml").write_text(SPEC)
    spec = load_spec(tmp_path / "s.toml")
    cells = expand(spec)
    assert [c.info["cells"] for c in cells] == [16, 32, 48, 64]
    assert cells[0].cost < cells[1].cost < cells[2].cost < cells[3].cost
    out = tmp_path / "out"
    done = {"dt": 1e-4, "particles": 8, "substeps": 10, "wall_s": 1.0, "error": 0.1, "unit": "%"}
    cache.store(out, cells[0], {"status": "ok", "device": "cpu", **done})
    cache.store(out, cells[1], {"status": "failed", "device": "cpu", "message": "boom"})
    cache.store(out, cells[2], {"status": "ok", "device": "cuda:0", **done})
    return spec, out


def listing(spec, out, world, **opts):
    launch = D.Launch(0, world, 0, world, "h:1") if world > 1 else D.Launch()
    rows = driver._listing(spec, launch, "cpu", driver.SweepOptions(out_dir=out, **opts))
    return [(c.info["cells"], status, rank) for c, status, rank in rows]


def test_listing_on_two_ranks_shows_every_cell_with_its_status_and_rank(four):
    """With two ranks every cell is listed, in order: cached ones (ok, and failed unless rerun_failed) with no
    rank, the others `pending` and dealt longest first to the least-loaded rank (1/64 to rank 0, then 1/48 to
    rank 1); a row cached by a GPU run is pending for a CPU run."""
    spec, out = four
    assert listing(spec, out, 2) == [(16, "ok", None), (32, "failed", None), (48, "pending", 1), (64, "pending", 0)]


def test_listing_on_two_ranks_deals_failed_cells_again_when_asked(four):
    """rerun_failed: a cached failure is dealt out like a pending cell (1/64 to rank 0, 1/48 then 1/32 to rank 1,
    the less loaded one); fresh ignores the cache and deals every cell (1/16 last, to rank 0)."""
    spec, out = four
    assert listing(spec, out, 2, rerun_failed=True) == [
        (16, "ok", None),
        (32, "failed", 1),
        (48, "pending", 1),
        (64, "pending", 0),
    ]
    assert listing(spec, out, 2, fresh=True) == [
        (16, "pending", 0),
        (32, "pending", 1),
        (48, "pending", 1),
        (64, "pending", 0),
    ]


def test_listing_on_one_rank_agrees_with_two_ranks_on_the_statuses(four):
    """One rank lists the same statuses (a cell to run goes to rank 0), cell by cell."""
    spec, out = four
    assert listing(spec, out, 1) == [(16, "ok", None), (32, "failed", None), (48, "pending", 0), (64, "pending", 0)]
    assert listing(spec, out, 1, rerun_failed=True)[1] == (32, "failed", 0)
    assert [s for _, s, _ in listing(spec, out, 1, fresh=True)] == ["pending"] * 4


# ---------------------------------------------------------------------------------------------
# progress lines


def test_a_failed_cells_line_gives_its_reason():
    """A failed cell's line: status, seconds to one decimal, and the message."""
    row = {"kind": "scene", "status": "failed", "cell_s": 12.34, "message": "diverged at frame 3: x"}
    assert driver._result(row) == "failed 12.3 s: diverged at frame 3: x"


def test_an_accuracy_cells_line_gives_its_error_and_unit():
    """A finished accuracy cell's line: status, seconds, the error in scientific notation with its unit."""
    row = {"kind": "accuracy", "status": "ok", "cell_s": 2.5, "error": 0.0123456, "unit": "% of period"}
    assert driver._result(row) == "ok 2.5 s, error 1.235e-02 (% of period)"


def test_a_scene_cells_line_gives_its_numeric_headline_metrics_in_order():
    """A finished scene cell's line lists latch frame, opening, penetration and substeps, in that order, each that
    is a number: integers as they are, floats to three significant digits; a missing key, null or a boolean is
    left out."""
    row = {"kind": "scene", "status": "ok", "cell_s": 3.0}
    full = {**row, "substeps": 120, "penetration_max": 0.28812, "opening": 1.23456, "latch_frame": 4}
    assert driver._result(full) == "ok 3.0 s, latch_frame 4, opening 1.23, penetration_max 0.288, substeps 120"
    some = {**row, "latch_frame": None, "opening": True, "penetration_max": 2.0, "substeps": False}
    assert driver._result(some) == "ok 3.0 s, penetration_max 2"
    assert driver._result(row) == "ok 3.0 s"
