"""Pinned rules of the sweep cache's strict reader (`fracture_gs.sweep.cache.check_row`): every key of a cached row
is checked, whatever its position (also after the nested `extra` table), each kind of wrong value is one
OutputError naming the file, the key, what the value is and the fix, and a finished accuracy row must hold the
numbers its table needs; a cache file that is no text, nests too deeply, is a folder or sits under a file is
refused naming it, and non-finite numbers are written as null so that the reader takes the file back.
"""

from __future__ import annotations

import math

import pytest

from fracture_gs.errors import OutputError
from fracture_gs.sweep import cache
from fracture_gs.sweep.expansion import Cell

FIX = "delete the file, or rerun with --fresh, to run the cell again."


def cell(kind="scene") -> Cell:
    return Cell(0, "0123456789ab", kind, {"kind": kind}, {}, ("t",))


def refused(tmp_path, row, kind="scene") -> str:
    path = tmp_path / "cells" / "0123456789ab.json"
    with pytest.raises(OutputError) as info:
        cache.check_row(path, cell(kind), row)
    text = str(info.value)
    assert text.startswith(f"{path}: the cached row's ") and text.endswith(FIX)
    return text[len(f"{path}: the cached row's ") : -len(FIX) - 2]


def test_keys_after_the_extra_table_are_still_checked(tmp_path):
    """The `extra` table is checked as a whole (an object, finite all the way down) and then the check goes on
    to the row's next keys: a NaN, a wrong type or a text integer after it is still refused; so is a wrong value
    after a null one."""
    extra = {"latch": {"latch_frame": 3, "latch_time": 0.03}, "fragments": [1, 2]}
    good = {"status": "ok", "extra": extra, "error": 0.5, "cells": 16}
    assert cache.check_row(None, cell(), dict(good)) == good
    assert refused(tmp_path, {"status": "ok", "extra": extra, "error": math.nan}) == "error is nan, not a finite number"
    assert refused(tmp_path, {"status": "ok", "extra": extra, "cells": "16"}) == (
        "cells is the string '16', not an integer"
    )
    assert refused(tmp_path, {"status": "ok", "extra": {}, "opening": [1]}) == (
        "opening is a list, not a number, text, true/false or null"
    )
    assert refused(tmp_path, {"status": "failed", "dt": None, "error": "x"}) == "error is the string 'x', not a number"


def test_extra_must_be_an_object_of_finite_numbers(tmp_path):
    """`extra` is an object; a NaN or inf anywhere inside it (nested tables, list entries) is refused naming its
    path."""
    assert refused(tmp_path, {"status": "ok", "extra": [1]}) == "extra is a list, not an object"
    assert refused(tmp_path, {"status": "ok", "extra": {"a": [0.0, math.inf]}}) == "extra.a[1] is not a finite number"
    assert refused(tmp_path, {"status": "ok", "extra": {"a": {"b": -math.inf}}}) == "extra.a.b is not a finite number"


def test_the_row_must_be_an_object_with_a_known_status(tmp_path):
    """A row is an object whose status is ok or failed (a `missing` row is never written): anything else is
    refused saying what it is."""
    assert refused(tmp_path, [1, 2]) == "row is a list, not an object"
    assert refused(tmp_path, None) == "row is null, not an object"
    assert refused(tmp_path, {"error": 1.0}) == "status is null, not one of ok, failed"
    assert refused(tmp_path, {"status": "missing"}) == "status is the string 'missing', not one of ok, failed"
    assert refused(tmp_path, {"status": True}) == "status is the boolean true, not one of ok, failed"
    assert refused(tmp_path, {"status": "ok", 3: "x"}) == "3 is not a text key"


@pytest.mark.parametrize(
    "key, value, problem",
    [
        ("wall_s", math.inf, "is inf, not a finite number"),
        ("anything", -math.inf, "is -inf, not a finite number"),
        ("anything", {"a": 1}, "is an object, not a number, text, true/false or null"),
        ("particles", 2.0, "is the number 2.0, not an integer"),
        ("frames", False, "is the boolean false, not an integer"),
        ("error", "0.1", "is the string '0.1', not a number"),
        ("cell_s", True, "is the boolean true, not a number"),
        ("unit", 5, "is the number 5, not text"),
        ("message", False, "is the boolean false, not text"),
    ],
)
def test_each_kind_of_wrong_value_is_named(tmp_path, key, value, problem):
    """Integer columns take integers (not floats or booleans), number columns numbers (not text or booleans), text
    columns text; any other key takes a finite number, text, true/false or null."""
    assert refused(tmp_path, {"status": "failed", key: value}) == f"{key} {problem}"


def test_null_and_right_types_pass_in_every_column_kind():
    """null passes in every column, and each column kind takes its own type (an integer is a number too); the row
    comes back unchanged."""
    row = {
        "status": "failed",
        "particles": 10,
        "frames": None,
        "error": 3,
        "wall_s": 0.25,
        "dt": None,
        "unit": "%",
        "message": None,
        "separated": True,
        "note": "x",
    }
    assert cache.check_row(None, cell(), dict(row)) == row


def test_a_finished_accuracy_row_holds_what_its_table_needs(tmp_path):
    """A finished accuracy row needs dt, particles, substeps, wall_s, error and unit (null counts as missing); a
    failed accuracy row, and a finished scene row, need none of them."""
    full = {"status": "ok", "dt": 1e-4, "particles": 8, "substeps": 10, "wall_s": 1.0, "error": 0.1, "unit": "%"}
    assert cache.check_row(None, cell("accuracy"), dict(full)) == full
    for key in ("dt", "particles", "substeps", "wall_s", "error", "unit"):
        row = {k: v for k, v in full.items() if k != key}
        assert refused(tmp_path, row, "accuracy") == f"{key} is missing from a finished accuracy cell"
        assert refused(tmp_path, {**full, key: None}, "accuracy") == f"{key} is missing from a finished accuracy cell"
    assert cache.check_row(None, cell("accuracy"), {"status": "failed"}) == {"status": "failed"}
    assert cache.check_row(None, cell("scene"), {"status": "ok"}) == {"status": "ok"}


# ---------------------------------------------------------------------------------------------
# files and folders


def test_a_cache_file_that_is_no_text_or_nests_too_deeply_is_refused_naming_it(tmp_path):
    """A cache file of bytes that are not UTF-8, or of JSON nested deeper than the parser's stack, is an OutputError
    naming the file and the fix, never a UnicodeDecodeError or RecursionError traceback."""
    c = cell()
    path = cache.cache_path(tmp_path, c.id)
    path.parent.mkdir(parents=True)
    path.write_bytes(b'{"id": "\xff\xfe"}')
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, c)
    assert str(info.value) == (
        f"{path} cannot be read as a sweep cache file (UnicodeDecodeError); delete it, or rerun with --fresh."
    )
    path.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, c)
    assert str(info.value) == f"{path} nests too deeply for a sweep cache file; delete it, or rerun with --fresh."


def test_writing_onto_a_folder_or_under_a_file_is_refused(tmp_path):
    """A cache file path that is a folder, or a cache folder with a file somewhere above it, is an OutputError
    naming that path and the fix; nothing is written."""
    c = cell()
    path = cache.cache_path(tmp_path, c.id)
    path.mkdir(parents=True)
    with pytest.raises(OutputError) as info:
        cache.store(tmp_path, c, {"status": "ok"})
    assert str(info.value) == f"{path} is a folder, not a sweep cache file; delete that folder and rerun."
    (tmp_path / "plain").write_text("x")
    with pytest.raises(OutputError) as info:
        cache.store(tmp_path / "plain" / "deeper", c, {"status": "ok"})
    assert str(info.value).startswith(f"{tmp_path / 'plain'} is a file, not the sweep's cache folder; move or delete")
    assert (tmp_path / "plain").read_text() == "x"


def test_non_finite_numbers_are_written_as_null_so_the_file_reads_back(tmp_path):
    """A row holding NaN or inf (in a list, a tuple or a nested table too) is cached with null in their place, and
    the strict reader takes it back."""
    c = cell()
    row = {"status": "ok", "error": math.nan, "dt": math.inf, "extra": {"span": (1.0, math.inf), "t": {"a": -math.inf}}}
    cache.store(tmp_path, c, row)
    assert cache.load(tmp_path, c) == {
        "status": "ok",
        "error": None,
        "dt": None,
        "extra": {"span": [1.0, None], "t": {"a": None}},
    }
