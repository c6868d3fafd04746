"""Hand-written bug campaign, round two: the sweep's cache reader and its dealing of cells (`sweep.cache`,
`sweep.driver`).

- A finished accuracy row simulated at least one particle and one substep: 0 in either is a damaged file, named.
- A NaN or inf anywhere inside a row's `extra` table is refused with its path, inside nested lists and objects too.
- Cells of equal estimated cost are dealt round-robin: pending cell j to rank j mod W, ties to the lower rank.
"""

import math

import pytest

from fracture_gs.errors import OutputError
from fracture_gs.sweep import cache
from fracture_gs.sweep.driver import deal
from fracture_gs.sweep.expansion import Cell

FIX = "delete the file, or rerun with --fresh, to run the cell again."


def _cell(kind="accuracy", index=0, cost=1.0) -> Cell:
    return Cell(index, f"{index:012x}", kind, {"kind": kind, "i": index}, {}, ("t",), cost=cost)


def _problem(tmp_path, row, kind="accuracy") -> str:
    path = tmp_path / "cells" / "000000000000.json"
    with pytest.raises(OutputError) as info:
        cache.check_row(path, _cell(kind), row)
    text = str(info.value)
    assert text.startswith(f"{path}: the cached row's ") and text.endswith(FIX), text
    return text[len(f"{path}: the cached row's ") : -len(FIX) - 2]


@pytest.mark.parametrize("key", ["particles", "substeps"])
def test_a_finished_accuracy_row_has_a_particle_and_a_substep(tmp_path, key):
    """An ok accuracy row with every key its table needs loads; with `key` = 0 it is refused naming the key."""
    row = {"status": "ok", "dt": 1e-3, "particles": 100, "substeps": 40, "wall_s": 1.5, "error": 0.01, "unit": "m"}
    assert cache.check_row(None, _cell(), dict(row)) == row
    row[key] = 0
    assert _problem(tmp_path, row) == f"{key} is 0, but a finished accuracy cell simulated at least one"


@pytest.mark.parametrize(
    "extra,where",
    [
        ({"opening": [0.1, math.nan]}, "extra.opening[1]"),
        ({"latch": [{"t": 0.1}, {"t": math.inf}]}, "extra.latch[1].t"),
        ({"a": {"b": [[1.0, -math.inf]]}}, "extra.a.b[0][1]"),
    ],
)
def test_a_non_finite_number_deep_inside_extra_is_named_by_its_path(tmp_path, extra, where):
    """Lists and objects nest inside `extra`; the first non-finite number is refused with its path."""
    assert _problem(tmp_path, {"status": "ok", "extra": extra}, kind="scene") == f"{where} is not a finite number"


def test_cells_of_equal_cost_are_dealt_round_robin_from_rank_0():
    """Six cells of cost 1 on three ranks: [[0, 3], [1, 4], [2, 5]]; one costly cell goes to rank 0, then the rest
    fill ranks 1 and 2 before rank 0 gets another."""
    cells = [_cell(index=i) for i in range(6)]
    assert deal(cells, 3) == [[0, 3], [1, 4], [2, 5]]
    cells = [_cell(index=0, cost=5.0)] + [_cell(index=i) for i in range(1, 5)]
    assert deal(cells, 3) == [[0], [1, 3], [2, 4]]
