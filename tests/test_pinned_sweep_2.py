"""Pinned rules of the sweep package, part two: the cache's check of nested numbers, the status of a scene
cell that diverged, the particle cap of a [[scene]] table and its reach into each cell's config, the cost of
a faster spin, the accuracy panel of the sweep table, message truncation, the warm-up switch, rank 0's
complete cache, the heartbeat's timeout and the teardown of a process group.

Unit-level calls only: no cell is simulated (the simulator is replaced where a cell function is called).
"""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import pytest

from fracture_gs.errors import ConfigError, OutputError
from fracture_gs.sweep import cache, driver
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.expansion import Cell, accuracy_cost, expand
from fracture_gs.sweep.report import sweep_table
from fracture_gs.sweep.spec import load_spec


def cell(i=0, kind="scene", config=None) -> Cell:
    return Cell(
        i, f"{i:012x}", kind, {"kind": kind, "i": i}, {"config": "bread", "variant": "full", "seed": 0}, ("t",), config
    )


# ---------------------------------------------------------------------------------------------
# cache rows


def test_a_nan_nested_inside_a_cached_rows_extra_is_refused_naming_its_path(tmp_path):
    """A cached row's `extra` table is searched all the way down: a NaN inside a nested table is an OutputError
    naming the file and the path to it (extra.latch.time), while finite nested numbers pass unchanged."""
    path = tmp_path / "cells" / "x.json"
    good = {"status": "ok", "extra": {"latch": {"time": 0.5}, "fragments": [1, 2]}}
    assert cache.check_row(path, cell(), good) == good
    for extra, where in (({"latch": {"time": math.nan}}, "extra.latch.time"), ({"t": math.inf}, "extra.t")):
        with pytest.raises(OutputError) as info:
            cache.check_row(path, cell(), {"status": "ok", "extra": extra})
        assert str(path) in str(info.value) and f"{where} is not a finite number" in str(info.value)


# ---------------------------------------------------------------------------------------------
# one scene cell


@pytest.mark.parametrize(
    "cause, status",
    [
        ("the stiffest material outran the step", "diverged at frame 3: the stiffest material outran the step"),
        ("", "diverged at frame 3: positions exploded"),
    ],
)
def test_a_diverged_scene_cell_reports_the_frame_and_the_cause(monkeypatch, cause, status):
    """A scene cell whose simulation diverges is an outcome, not an exception: its status names the frame and
    the likely cause the solver gave, or the solver's own message when it gave no cause."""
    import fracture_gs.pipeline as pipeline
    import fracture_gs.render_sim as runner
    from fracture_gs.io.config import config_from_dict, config_to_dict
    from fracture_gs.render_sim import VariantSummary
    from fracture_gs.sim import SimulationDiverged
    from fracture_gs.sweep.cells import run_cell

    def simulate(sim, cov0, frames, frame_dt, carrier=None):
        raise SimulationDiverged("positions exploded", 3, 7, cause)
        yield  # a generator, as the real one

    monkeypatch.setattr(pipeline, "make_simulator", lambda cfg, gs, variant, device: SimpleNamespace(dt=1e-4))
    monkeypatch.setattr(pipeline, "simulate", simulate)
    monkeypatch.setattr(
        runner, "summarize", lambda variant, rows, st, wall: VariantSummary(variant, st, 0, 0, wall, None, None, None)
    )
    config = config_to_dict(config_from_dict({"variants": ["baseline"], "frames": 4, "particles": 200}))
    c = Cell(0, "abc", "scene", {"variant": "baseline", "seed": 0}, {}, ("t",), config)
    out = run_cell(c, "cpu", None)
    assert out.status == status
    assert out.metrics["frames"] == 4 and out.metrics["dt"] == pytest.approx(1e-4)


# ---------------------------------------------------------------------------------------------
# spec and expansion


def test_scene_particles_are_capped_at_one_hundred_million(tmp_path):
    """A [[scene]] table's particles may be at most 100,000,000 (the bound its message names); one more is a
    ConfigError naming scene[0].particles."""
    path = tmp_path / "s.toml"
    path.write_text('[[scene]]\nconfig = "bread"\nparticles = 100_000_000\n')
    assert load_spec(path).scenes[0].particles == 100_000_000
    path.write_text('[[scene]]\nconfig = "bread"\nparticles = 100_000_001\n')
    with pytest.raises(
        ConfigError, match=r"scene\[0\]\.particles value 100000001 must be an integer in \[1, 100000000\]"
    ):
        load_spec(path)


def test_a_scene_tables_particles_reach_each_cells_config(tmp_path):
    """particles = N in a [[scene]] table sets the particle count of every cell it makes; a table without it
    keeps the base config's own count."""
    from fracture_gs.io.config import load_config

    path = tmp_path / "s.toml"
    path.write_text('[[scene]]\nconfig = "bread"\nvariant = "baseline"\nparticles = 321\n')
    (only,) = expand(load_spec(path))
    assert only.config["particles"] == 321
    path.write_text('[[scene]]\nconfig = "bread"\nvariant = "baseline"\n')
    (only,) = expand(load_spec(path))
    base = load_config("bread").particles
    assert base != 321 and only.config.get("particles") == base


def test_a_faster_spin_costs_more(monkeypatch):
    """The spin case's substeps follow the fastest signal, the P-wave speed plus the rim speed ω·a/2: spinning
    faster (everything else equal) makes the cell's estimated cost larger."""
    from fracture_gs.paper import accuracy as A

    slow = accuracy_cost("spin", 16, 0.4)
    monkeypatch.setitem(A.SPIN, "omega", A.SPIN["omega"] * 10 + 100.0)
    assert accuracy_cost("spin", 16, 0.4) > slow


# ---------------------------------------------------------------------------------------------
# outputs and messages


def test_the_accuracy_panel_keeps_each_rows_numbers_and_writes_dx_as_a_fraction():
    """The sweep table's accuracy panel holds every accuracy row with its own numbers, Δx written as 1/cells,
    and the Pareto flag only for finished rows; scene rows go to the scene panel."""
    base = {"kind": "accuracy", "case": "bar", "cfl": 0.4, "wall_s": 1.0, "unit": "%"}
    rows = [
        {**base, "id": "a", "status": "ok", "cells": 16, "error": 0.02},
        {**base, "id": "b", "status": "failed", "cells": 32, "error": None, "message": "boom"},
        {"id": "c", "kind": "scene", "status": "ok"},
    ]
    table = sweep_table("T", rows, "cap", "cmd")
    acc, scene = table.panels
    assert [(r["id"], r["cells"], r["error"], r["dx_text"], r["pareto"]) for r in acc.rows] == [
        ("a", 16, 0.02, "1/16", True),
        ("b", 32, None, "1/32", None),
    ]
    assert [r["id"] for r in scene.rows] == ["c"]


def test_long_messages_are_cut_to_their_limit_with_an_ellipsis():
    """A cell's failure message is at most 400 characters and a rank's first line of an error at most 200;
    a longer text keeps its start and ends in '...', a text at the limit is kept whole."""
    long = driver._message(RuntimeError("x" * 1000))
    assert len(long) == 400 and long.endswith("x...") and long.startswith("RuntimeError: x")
    exact = "RuntimeError: " + "y" * (400 - len("RuntimeError: "))
    assert driver._message(RuntimeError("y" * (400 - len("RuntimeError: ")))) == exact
    first = D._first_line(ValueError("z" * 500))
    assert len(first) == 200 and first == "z" * 197 + "..."
    assert D._first_line(ValueError("w" * 200)) == "w" * 200


# ---------------------------------------------------------------------------------------------
# the driver


@pytest.mark.parametrize("wanted", [True, False])
def test_warmup_runs_only_when_the_spec_asks(monkeypatch, tmp_path, wanted):
    """A rank compiles and loads the kernels before its first cell exactly when the spec's warmup is on."""
    calls = []
    monkeypatch.setattr(driver, "warmup", lambda device: calls.append(device))
    monkeypatch.setattr(
        driver, "run_one", lambda c, launch, dev, out: {**driver.base_row(c), "status": "ok", "cell_s": 0.0}
    )
    rows = driver._run_mine(
        SimpleNamespace(warmup=wanted), [cell(0)], 1, D.Launch(), "cpu", tmp_path, lambda s: None, [0]
    )
    assert list(rows) == [cell(0).id]
    assert calls == (["cpu"] if wanted else [])


def test_rank_zero_writes_gathered_rows_it_has_not_cached(tmp_path):
    """Rank 0 keeps a complete cache: a finished row gathered from another node is written to its cache, a row
    already cached there is left as it is, and a `missing` row is never cached."""
    a, b, c = cell(0), cell(1), cell(2)
    cache.store(tmp_path, b, {"status": "ok", "error": 1.0})
    driver._complete_cache(
        tmp_path, [a, b, c], [{"status": "ok", "error": 0.5}, {"status": "ok", "error": 2.0}, {"status": "missing"}]
    )
    assert cache.load(tmp_path, a) == {"status": "ok", "error": 0.5}
    assert cache.load(tmp_path, b) == {"status": "ok", "error": 1.0}
    assert cache.load(tmp_path, c) is None


# ---------------------------------------------------------------------------------------------
# the store protocol


def test_a_rank_silent_for_less_than_the_timeout_is_not_dead():
    """The heartbeat marks a rank dead only after it has been silent for longer than the timeout: a rank that
    never beats within a 10 s timeout is still alive after a fraction of a second of watching."""
    from test_pinned_sweep import coordinator

    coord = coordinator(0, 2, timeout_s=10.0, beat_s=0.01)
    thread = threading.Thread(target=coord._heartbeat, daemon=True)
    thread.start()
    time.sleep(0.2)
    coord._stop.set()
    thread.join(2)
    assert int(coord.store.get(coord._key("beat", 0))) > 3  # it did watch, many times
    assert coord.dead == {}


@pytest.mark.parametrize(
    "initialized, failed, dead, destroyed",
    [(True, False, {}, True), (True, True, {}, False), (True, False, {1: "gone"}, False), (False, False, {}, False)],
)
def test_close_tears_the_process_group_down_only_when_every_rank_is_well(
    monkeypatch, initialized, failed, dead, destroyed
):
    """close destroys the process group only when one exists and no rank failed or died (destroying it then
    would wait on the dead rank); a group never made is left alone."""
    import torch.distributed as dist
    from test_pinned_sweep import coordinator

    calls = []
    monkeypatch.setattr(dist, "is_initialized", lambda: initialized)
    monkeypatch.setattr(dist, "destroy_process_group", lambda *a, **k: calls.append(1))
    coord = coordinator(0, 2)
    coord._failed, coord.dead = failed, dict(dead)
    coord.close()
    assert calls == ([1] if destroyed else [])
