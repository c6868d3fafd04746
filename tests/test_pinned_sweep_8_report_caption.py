"""Pinned rules of a sweep's tables (`fracture_gs.sweep.report.write_outputs`): the output folder is made with its
missing parents (`--out runs/2026/sweep` on a fresh machine), and the caption of sweep.md and sweep.tex states the
cell counts, the world size and the devices that ran cells, each device once, sorted, with its name, or `none`
when no row ran anywhere (every cell missing), then the date.

Unit-level: rows are written, nothing is simulated; the date is fixed.
"""

from __future__ import annotations

import datetime
import json
from types import SimpleNamespace

import pytest

from fracture_gs.sweep import report

ROWS = [
    {"id": "a", "kind": "scene", "status": "ok", "device": "cuda:1", "device_name": "H100"},
    {"id": "b", "kind": "scene", "status": "failed", "message": "boom", "device": "cpu", "device_name": "x86"},
    {"id": "c", "kind": "scene", "status": "ok", "device": "cuda:1", "device_name": "H100"},
    {"id": "d", "kind": "scene", "status": "missing"},
]


@pytest.fixture
def fixed_date(monkeypatch):
    today = SimpleNamespace(today=lambda: datetime.date(2030, 1, 2))
    monkeypatch.setattr(report, "datetime", SimpleNamespace(date=today))


def _spec(tmp_path):
    return SimpleNamespace(source="s.toml", title="T", path=tmp_path / "s.toml")


def test_outputs_go_into_a_folder_made_with_its_parents_and_name_each_device_once(tmp_path, fixed_date):
    """Writing into runs/2026/sweep where not even runs/ exists makes the whole path; the caption (in sweep.md and
    in sweep.tex) counts 2 ok, 1 failed, 1 missing, names world size 3 and the two devices that ran cells, sorted
    and once each with their names; sweep.json lists the same devices."""
    out = tmp_path / "runs" / "2026" / "sweep"
    assert report.write_outputs(out, _spec(tmp_path), ROWS, 3, "cmd") == [
        "sweep.md",
        "sweep.tex",
        "sweep.csv",
        "sweep.json",
    ]
    head = "4 cells from s.toml: 2 ok, 1 failed, 1 missing; world size 3; devices cpu: x86, cuda:1: H100; 2030-01-02. "
    assert head in (out / "sweep.md").read_text() and "\\caption{" + head in (out / "sweep.tex").read_text()
    assert json.loads((out / "sweep.json").read_text())["devices"] == ["cpu: x86", "cuda:1: H100"]


def test_a_sweep_where_no_row_ran_says_devices_none(tmp_path, fixed_date):
    """When every cell is missing (no row names a device), the caption says `devices none` rather than leaving the
    list blank, and sweep.json's device list is empty."""
    rows = [{"id": "a", "kind": "scene", "status": "missing"}, {"id": "b", "kind": "scene", "status": "missing"}]
    out = tmp_path / "out"
    report.write_outputs(out, _spec(tmp_path), rows, 2)
    assert (
        "2 cells from s.toml: 0 ok, 0 failed, 2 missing; world size 2; devices none; 2030-01-02. "
        in (out / "sweep.md").read_text()
    )
    assert json.loads((out / "sweep.json").read_text())["devices"] == []
