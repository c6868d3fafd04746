"""Pinned rules of one sweep cell (`fracture_gs.sweep.cells`): the wall time and metrics of a scene cell, the
seed that reaches its asset, a rendered cell's quiet render-sim call, an accuracy cell's call of its case and
the kinds a cell may have.

Unit-level calls only: the simulator, the frame loop, render-sim and the accuracy case are replaced by fakes
(the real summary function `render_sim.summarize` turns the fake frame rows into metrics).
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch

from fracture_gs.io.config import config_from_dict, config_to_dict
from fracture_gs.sweep import cells as C
from fracture_gs.sweep.expansion import Cell


def scene_cell(seed=0, render=False, frames=4, cid="abc") -> Cell:
    config = config_to_dict(config_from_dict({"variants": ["baseline"], "frames": frames, "particles": 200}))
    params = {"variant": "baseline", "seed": seed, "render": render}
    return Cell(0, cid, "scene", params, {}, ("t",), config)


def fake_loop(monkeypatch, dt=1e-4, seconds_per_frame=1.25, rows=None):
    """Replace the simulator and the frame loop; the fake clock of `cells` advances only while frames run.
    Returns the list the fake simulator appends (gaussians, variant, device) to."""
    import fracture_gs.pipeline as pipeline

    clock = [1000.0]
    made = []
    rows = rows if rows is not None else [{"frame": 1, "substeps": 4}, {"frame": 2, "substeps": 10}]

    def make_simulator(cfg, gs, variant, device):
        made.append((gs, variant, device))
        return SimpleNamespace(dt=dt)

    def simulate(sim, cov0, frames, frame_dt, carrier=None):
        for row in rows:
            clock[0] += seconds_per_frame
            yield SimpleNamespace(metrics=row)

    monkeypatch.setattr(pipeline, "make_simulator", make_simulator)
    monkeypatch.setattr(pipeline, "simulate", simulate)
    monkeypatch.setattr(C, "time", SimpleNamespace(perf_counter=lambda: clock[0]))
    return made


# ---------------------------------------------------------------------------------------------
# a scene cell without rendering


def test_a_scene_cells_wall_time_is_the_time_its_frames_took(monkeypatch):
    """A scene cell's wall_s is the seconds between the start and the end of its frame loop (two frames of
    1.25 s each: 2.5 s, whatever the clock read when it started), and substeps/s is the last frame's substep
    count over that time (10 / 2.5 = 4)."""
    fake_loop(monkeypatch)
    out = C.run_cell(scene_cell(), "cpu", None)
    assert out.status == "ok"
    assert out.metrics["wall_s"] == pytest.approx(2.5)
    assert out.metrics["substeps"] == 10 and out.metrics["substeps_per_s"] == pytest.approx(4.0)


def test_a_scene_cells_metrics_are_the_summary_flattened(monkeypatch):
    """A scene cell's metrics are render-sim's summary flattened: the config's frame count (not the last frame
    simulated), the particles made, the solver's Δt, no latch frame or time before any latch; the summary's
    variant and status are not metrics (the status is the outcome's)."""
    made = fake_loop(monkeypatch, dt=2.5e-4)
    out = C.run_cell(scene_cell(frames=4), "cpu", None)
    ((gs, variant, device),) = made
    assert (variant, device) == ("baseline", "cpu")
    assert len(gs) == 200 and out.metrics["particles"] == 200
    assert out.metrics["frames"] == 4
    assert out.metrics["dt"] == pytest.approx(2.5e-4)
    assert out.metrics["latch_frame"] is None and out.metrics["latch_time"] is None
    assert "variant" not in out.metrics and "status" not in out.metrics


def test_a_scene_cell_with_no_finite_step_reports_dt_as_null(monkeypatch):
    """A solver whose Δt is not a finite number (inf before its first adaptive step) gives dt = null, never a
    non-finite number in the row (the cache refuses NaN and inf)."""
    fake_loop(monkeypatch, dt=math.inf)
    out = C.run_cell(scene_cell(), "cpu", None)
    assert out.metrics["dt"] is None


def test_a_scene_cells_seed_picks_its_asset_sample(monkeypatch):
    """The cell's seed is the built-in asset's sampling seed: the same seed gives the same particles, another
    seed other particles."""
    made = fake_loop(monkeypatch)
    for seed in (0, 0, 1):
        C.run_cell(scene_cell(seed=seed), "cpu", None)
    a, b, c = (m[0].means for m in made)
    assert torch.equal(a, b)
    assert not torch.allclose(a, c)


def test_flat_lifts_the_latch_and_keeps_tables_and_lists_as_extras():
    """_flat: numbers, strings and null stay flat; tables and lists (also tuples, as lists) go to the extras;
    variant, status and interrupted are dropped; the latch's frame and time are lifted into the flat metrics."""
    summary = {
        "variant": "full",
        "status": "ok",
        "interrupted": False,
        "opening": 1.5,
        "separated": True,
        "note": "x",
        "first_contact_time": None,
        "latch": {"latch_frame": 7, "latch_time": 0.07},
        "span": (1, 2),
        "fragments_list": [3, 4],
    }
    flat, extra = C._flat(summary)
    assert flat == {
        "opening": 1.5,
        "separated": True,
        "note": "x",
        "first_contact_time": None,
        "latch_frame": 7,
        "latch_time": 0.07,
    }
    assert extra == {"latch": {"latch_frame": 7, "latch_time": 0.07}, "span": [1, 2], "fragments_list": [3, 4]}


# ---------------------------------------------------------------------------------------------
# a rendered scene cell


def test_a_rendered_cell_runs_render_sim_quietly_under_its_own_folder(monkeypatch, tmp_path):
    """render = true runs render-sim without its own progress bars (the sweep prints one line per cell; bars of
    every cell would interleave across ranks), writing under OUT/cells/<id>/ (./cells/<id>/ without an output
    folder); a variant summary without a status is `ok`."""
    import fracture_gs.render_sim as runner
    from fracture_gs.render_sim import RunSummary

    calls = []

    def fake_render_sim(cfg, variants, device, folder, progress=True):
        calls.append((folder, progress))
        return RunSummary("c", "bread", "small", device, 50, [], 3, 0.01, [{"variant": variants[0], "opening": 0.5}])

    monkeypatch.setattr(runner, "run_render_sim", fake_render_sim)
    out = C.run_cell(scene_cell(render=True, cid="r1"), "cpu", tmp_path)
    assert calls == [(tmp_path / "cells" / "r1", False)]
    assert out.status == "ok" and out.metrics["particles"] == 50 and out.metrics["opening"] == 0.5
    C.run_cell(scene_cell(render=True, cid="r2"), "cpu", None)
    assert calls[1] == (Path(".") / "cells" / "r2", False)


# ---------------------------------------------------------------------------------------------
# an accuracy cell, and the kinds


def test_an_accuracy_cell_calls_its_case_at_one_over_cells_and_keeps_scalar_extras(monkeypatch):
    """An accuracy cell calls its case with Δx = 1/cells, its CFL number, the device and its first label, and
    reports the case's numbers plus those extras that are scalars (a table or a list is left out of the row)."""
    from fracture_gs.paper import accuracy

    calls = []

    def case(dx, cfl, device, label):
        calls.append((dx, cfl, device, label))
        extra = {"period": 0.1, "ok": True, "name": "n", "none": None, "curve": [1, 2], "table": {"a": 1}}
        return SimpleNamespace(
            dt=1e-4, particles=64, substeps=300, wall_s=0.5, error=0.02, unit="%", detail="d", extra=extra
        )

    monkeypatch.setitem(accuracy.CASES, "bar", case)
    cell = Cell(0, "acc", "accuracy", {"case": "bar", "cells": 16, "cfl": 0.4}, {}, ("dx", "cfl"))
    out = C.run_cell(cell, "cpu", None)
    assert calls == [(1 / 16, 0.4, "cpu", "dx")]
    assert out.status == "ok" and out.extra == {}
    assert out.metrics == {
        "dt": 1e-4,
        "particles": 64,
        "substeps": 300,
        "wall_s": 0.5,
        "error": 0.02,
        "unit": "%",
        "detail": "d",
        "period": 0.1,
        "ok": True,
        "name": "n",
        "none": None,
    }


def test_a_cell_of_another_kind_is_refused_naming_it():
    """Only accuracy and scene cells run: another kind is a ValueError naming the cell and the kind."""
    with pytest.raises(ValueError, match=r"cell xyz: unknown kind 'render'"):
        C.run_cell(Cell(0, "xyz", "render", {}, {}, ("t",)), "cpu", None)
