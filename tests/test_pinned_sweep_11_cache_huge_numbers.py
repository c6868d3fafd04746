"""The sweep cache's strict reader (`fracture_gs.sweep.cache.check_row`) refuses an integer too large for a float
(JSON has no size limit on integers: a 400-digit integer overflows `float()`, so no table or sum could use it):
the message names the key and shows the number cut to its first 60 characters ("the number " and 49 digits), so
a damaged file cannot flood the terminal; an integer that still fits a float (10**308) passes, 10**309 does not.
A number column (error, dt, ...) says "not a number" first; the check runs in any column, known or not.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import OutputError
from fracture_gs.sweep import cache
from fracture_gs.sweep.expansion import Cell

FIX = "delete the file, or rerun with --fresh, to run the cell again."
HUGE = 10**400
"""401 digits: float(HUGE) raises OverflowError."""


def cell() -> Cell:
    return Cell(0, "0123456789ab", "scene", {"kind": "scene"}, {}, ("t",))


def problem(tmp_path, row) -> str:
    """The middle of the refusal: what is wrong with which key."""
    path = tmp_path / "cells" / "0123456789ab.json"
    with pytest.raises(OutputError) as info:
        cache.check_row(path, cell(), row)
    text = str(info.value)
    head = f"{path}: the cached row's "
    assert text.startswith(head) and text.endswith(FIX), text
    return text[len(head) : -len(FIX) - 2]


@pytest.mark.parametrize("key", ["particles", "frames", "anything"])
def test_a_huge_integer_is_refused_showing_its_first_sixty_characters(tmp_path, key):
    """An integer column (particles, frames) or a column of its own ("anything") holding 10**400 is refused as
    too large for a number; the value is shown as "the number " and its first 49 digits, 60 characters in all
    (one more or one less digit is a different message); a negative one shows its sign and 48 digits."""
    shown = "the number 1" + "0" * 48
    assert len(shown) == 60
    assert problem(tmp_path, {"status": "failed", key: HUGE}) == f"{key} is {shown}, too large for a number"
    negative = "the number -1" + "0" * 47
    assert len(negative) == 60
    if key == "anything":  # an integer column refuses a negative count first (bound 0)
        assert problem(tmp_path, {"status": "failed", key: -HUGE}) == f"{key} is {negative}, too large for a number"


def test_ten_to_the_308_passes_and_ten_to_the_309_is_refused(tmp_path):
    """10**309 is 310 digits, still cut to 49; the largest power of ten a float holds, 10**308, passes in an
    integer column and in one of its own, and the row comes back unchanged."""
    assert problem(tmp_path, {"status": "ok", "seed": 10**309}) == (
        "seed is the number 1" + "0" * 48 + ", too large for a number"
    )
    row = {"status": "ok", "seed": 10**308, "anything": 10**308}
    assert cache.check_row(None, cell(), dict(row)) == row


def test_a_huge_integer_in_a_number_column_is_not_a_number(tmp_path):
    """error, dt, cfl, cell_s and wall_s are computed with: a 401-digit integer there is refused as "not a
    number" (the number column's own check, before the general size check), its value cut to 60 characters like
    the size check's, so the refusal stays one short sentence."""
    for key in ("error", "dt", "cfl", "cell_s", "wall_s"):
        text = problem(tmp_path, {"status": "failed", key: HUGE})
        assert text == f"{key} is the number 1{'0' * 48}, not a number", text


def test_a_cache_file_with_a_huge_integer_is_refused_naming_the_file(tmp_path):
    """End to end through the file: a cache file whose row holds a 401-digit integer (valid JSON) is one
    OutputError naming the file, the key, the cut number and the fix, never an OverflowError."""
    c = cell()
    cache.store(tmp_path, c, {"status": "failed", "particles": HUGE})
    path = cache.cache_path(tmp_path, c.id)
    assert str(HUGE) in path.read_text()
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, c)
    assert str(info.value) == (
        f"{path}: the cached row's particles is the number 1{'0' * 48}, too large for a number; {FIX}"
    )
