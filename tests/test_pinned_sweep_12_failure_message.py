"""A failed cell's row message (`fracture_gs.sweep.driver._message`): the package's own errors are already one
sentence with the fix, so they are shown as they are; anything else (a bug, a library's error) is prefixed
with its class name so the reader knows what raised it; an error with no text (or only whitespace) shows its
class name alone, never an empty message. Whitespace runs (newlines of a multi-line error) become one space.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError, FractureGSError, OutputError, PlyError, SceneError, SimulationDiverged
from fracture_gs.sweep import driver
from fracture_gs.sweep.distributed import Launch
from fracture_gs.sweep.expansion import Cell


@pytest.mark.parametrize(
    ("exc", "shown"),
    [
        (ConfigError("a.toml", "sim.dt", "sim.dt must be > 0; set it."), "a.toml: sim.dt must be > 0; set it."),
        (FractureGSError("plain package error"), "plain package error"),
        (SimulationDiverged("the run\n   diverged\tat frame 3", 3, 1), "the run diverged at frame 3"),
        (ConfigError("", None, ""), "ConfigError"),
        (PlyError(), "PlyError"),
        (OutputError("  \n "), "OutputError"),
        (ValueError("bad value"), "ValueError: bad value"),
        (KeyError("k"), "KeyError: 'k'"),
        (RuntimeError(""), "RuntimeError"),
        (ZeroDivisionError("a\n\nb"), "ZeroDivisionError: a b"),
    ],
)
def test_package_errors_are_shown_as_is_others_with_their_class(exc, shown):
    """Package error with text -> the text (whitespace collapsed); package error without text -> its class
    name; any other error -> "Class: text", or the class name alone when it has no text."""
    assert driver._message(exc) == shown


def test_a_long_package_error_is_cut_without_a_class_prefix():
    """A package error is cut to 400 characters like any other, still without a prefix: 397 of its characters
    and '...'; one of exactly 400 is kept whole."""
    assert driver._message(SceneError("c" * 401)) == "c" * 397 + "..."
    assert driver._message(SceneError("d" * 400)) == "d" * 400


def test_a_failing_cell_row_carries_the_message(monkeypatch, tmp_path):
    """run_one turns an exception into a failed row: a package error's sentence verbatim, another error with
    its class name, an empty package error as its class name (never an empty message)."""
    cell = Cell(0, "0123456789ab", "scene", {"kind": "scene"}, {}, ("t",))
    for exc, shown in [
        (ConfigError("", "scene.preset", "scene.preset is unknown; pick one."), "scene.preset is unknown; pick one."),
        (IndexError("list index out of range"), "IndexError: list index out of range"),
        (SceneError(), "SceneError"),
    ]:

        def boom(cell, device, out_dir, exc=exc):
            raise exc

        monkeypatch.setattr(driver, "run_cell", boom)
        row = driver.run_one(cell, Launch(), "cpu", tmp_path)
        assert (row["status"], row["message"]) == ("failed", shown)
        assert type(exc).__name__ in row["traceback"]
