"""The sweep cache's strict reader (`fracture_gs.sweep.cache.check_row`) refuses numbers no run writes: a negative
count, time or error (bound 0, inclusive: 0 itself passes) and a step or CFL number that is not above 0 (0 itself
is refused); the message names the key, the value and the bound as the user would fix it, e.g. "particles is -1,
not at least 0". A finished accuracy cell simulated at least one particle and one substep."""

from __future__ import annotations

import pytest

from fracture_gs.errors import OutputError
from fracture_gs.sweep import cache
from fracture_gs.sweep.expansion import Cell

FIX = "delete the file, or rerun with --fresh, to run the cell again."


def cell(kind="scene") -> Cell:
    return Cell(0, "0123456789ab", kind, {"kind": kind}, {}, ("t",))


def problem(tmp_path, row, kind="scene") -> str:
    """The middle of the refusal: what is wrong with which key."""
    path = tmp_path / "cells" / "0123456789ab.json"
    with pytest.raises(OutputError) as info:
        cache.check_row(path, cell(kind), row)
    text = str(info.value)
    head = f"{path}: the cached row's "
    assert text.startswith(head) and text.endswith(FIX), text
    return text[len(head) : -len(FIX) - 2]


@pytest.mark.parametrize("key", sorted(cache.INT_KEYS))
def test_a_negative_count_is_refused_and_zero_passes(tmp_path, key):
    """Every integer column (index, cells, seed, particles, frames, ...) is at least 0: -1 is refused naming the
    bound 0; 0 and 1 pass unchanged."""
    assert problem(tmp_path, {"status": "failed", key: -1}) == f"{key} is -1, not at least 0 (no run writes that)"
    for ok in (0, 1):
        assert cache.check_row(None, cell(), {"status": "failed", key: ok}) == {"status": "failed", key: ok}


@pytest.mark.parametrize("key", ["cell_s", "wall_s", "error"])
def test_a_negative_time_or_error_is_refused_and_zero_passes(tmp_path, key):
    """Times and errors are at least 0: -0.5 (and the smallest negative float) is refused naming the bound 0; 0.0 and
    0 pass."""
    assert problem(tmp_path, {"status": "ok", key: -0.5}) == f"{key} is -0.5, not at least 0 (no run writes that)"
    assert problem(tmp_path, {"status": "ok", key: -5e-324}) == f"{key} is -5e-324, not at least 0 (no run writes that)"
    for ok in (0.0, 0, 2.5):
        assert cache.check_row(None, cell(), {"status": "ok", key: ok}) == {"status": "ok", key: ok}


@pytest.mark.parametrize("key", ["dt", "cfl"])
def test_a_step_or_cfl_number_must_be_above_zero(tmp_path, key):
    """Δt and the CFL number are above 0: 0.0, 0 and -0.1 are refused ("not above 0"); 1e-9 passes."""
    for bad in (0.0, 0, -0.1):
        assert problem(tmp_path, {"status": "ok", key: bad}) == f"{key} is {bad!r}, not above 0 (no run writes that)"
    assert cache.check_row(None, cell(), {"status": "ok", key: 1e-9}) == {"status": "ok", key: 1e-9}


@pytest.mark.parametrize("key", ["particles", "substeps"])
def test_a_finished_accuracy_cell_simulated_at_least_one(tmp_path, key):
    """A finished accuracy row with 0 particles or 0 substeps is damaged (the run simulated at least one); 1 passes;
    a failed accuracy row may hold 0."""
    full = {"status": "ok", "dt": 1e-4, "particles": 8, "substeps": 10, "wall_s": 1.0, "error": 0.1, "unit": "%"}
    assert problem(tmp_path, {**full, key: 0}, "accuracy") == (
        f"{key} is 0, but a finished accuracy cell simulated at least one"
    )
    assert cache.check_row(None, cell("accuracy"), {**full, key: 1}) == {**full, key: 1}
    assert cache.check_row(None, cell("accuracy"), {"status": "failed", key: 0}) == {"status": "failed", key: 0}
