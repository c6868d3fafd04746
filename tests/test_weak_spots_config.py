"""Weak spots of config validation and the sweep cache (issue 34): every validation branch at its edge (one value
passes, the next fails, for fixed and adaptive Δt, on every axis) and every condition under which a cached row may be
reused. In-process calls only. Every test names the bug it was checked against (applied by hand to the package, the
test failed, then reverted)."""

import copy

import pytest

from fracture_gs.config import CuboidBoundary, ParticleRegion, SceneConfig, SphereBoundary
from fracture_gs.errors import ConfigError
from fracture_gs.io.config.validate import validate
from fracture_gs.sweep import cache
from fracture_gs.sweep.expansion import Cell


def scene(**sim):
    """A default scene config with `sim` fields set (valid as it comes: the tests below change one thing)."""
    cfg = copy.deepcopy(SceneConfig())
    cfg.topology.provider = "oracle"  # the default variants need one
    for k, v in sim.items():
        setattr(cfg.sim, k, v)
    return cfg


def fails(cfg, field: str) -> None:
    with pytest.raises(ConfigError) as e:
        validate(cfg, "t")
    assert e.value.field == field, str(e.value)


def test_the_default_scene_is_valid():
    """The baseline every test below changes one value of: it must pass, or the failures below prove nothing."""
    validate(scene(), "t")


@pytest.mark.parametrize("adaptive", [False, True])
def test_substep_bounds_hold_for_fixed_and_adaptive_dt(adaptive):
    """Δt is the substep with fixed Δt and its upper bound with adaptive Δt; either way a frame needs at least
    frame_dt / Δt substeps, so Δt > frame_dt and frame_dt / Δt > max_substeps_per_frame are refused for both (the
    solver would raise at the first frame: `frame_substeps`). Exactly max_substeps_per_frame substeps pass.
    Bugs tried: the substep-count check guarded by `s.adaptive_dt` (runs only for adaptive Δt), and by
    `not s.adaptive_dt` (only for fixed: a config certain to fail at its first frame passed); the Δt > frame_dt
    check guarded by either. Each fails here (the second was in the package: fixed)."""
    fails(scene(adaptive_dt=adaptive, dt=0.02), "sim.dt")  # frame_dt = 0.01 by default
    cfg = scene(adaptive_dt=adaptive, max_substeps_per_frame=100)
    cfg.sim.dt = cfg.frame_dt / 100
    cfg.material.E = 1e4  # bread's 2 MPa needs 186 CFL substeps a frame: over 100, refused since round five
    validate(cfg, "t")
    cfg.sim.max_substeps_per_frame = 99
    fails(cfg, "sim.max_substeps_per_frame")


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_every_grid_axis_holds_both_walls_and_a_stencil(axis):
    """An explicit grid needs, on every axis, the wall cells at both ends plus two free nodes (2·wall_cells + 2), and
    never fewer than 5 nodes (what `Grid` accepts): with 5 wall cells 12 nodes pass and 11 fail; with one wall cell 5
    pass and 4 fail (validation, not a later SimulationError).
    Bugs tried: `2 * s.wall_cells + 2` as `s.wall_cells + 2` (grid shape against one wall only), `n < …` as
    `n <= …`, only axis 0 checked; each fails here. The floor of 4 (below `Grid`'s 5) was in the package: fixed."""
    for walls, ok in ((5, 12), (1, 5)):
        shape = [64, 64, 64]
        shape[axis] = ok
        validate(scene(grid="explicit", wall_cells=walls, grid_shape=tuple(shape)), "t")
        shape[axis] = ok - 1
        fails(scene(grid="explicit", wall_cells=walls, grid_shape=tuple(shape)), f"sim.grid_shape[{axis}]")


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_boxes_need_positive_thickness_on_every_axis(axis):
    """A cuboid, a particle region and the grid bounds are boxes with lower < upper on every axis: a box of zero
    thickness on any one axis holds no node and acts nowhere, so it is refused; an inverted one too.
    Bug tried: `_Checker.box` with `lo < hi` as `lo <= hi` (zero-thickness boxes accepted): fails here."""
    lower, upper = [0.1, 0.1, 0.1], [0.4, 0.4, 0.4]
    for hi in (0.1, 0.05):  # zero thickness, inverted
        up = list(upper)
        up[axis] = hi
        fails(scene(boundaries=[CuboidBoundary(lower=tuple(lower), upper=tuple(up))]), "sim.boundaries[0].lower")
        region = ParticleRegion(lower=tuple(lower), upper=tuple(up), kind="impulse")
        fails(scene(boundaries=[region]), "sim.boundaries[0].lower")
        fails(scene(grid_bounds=(tuple(lower), tuple(up))), "sim.grid_bounds.lower")
    validate(scene(boundaries=[CuboidBoundary(lower=tuple(lower), upper=tuple(upper))]), "t")


@pytest.mark.parametrize("kind", ["cuboid", "sphere", "region"])
def test_active_intervals_start_at_or_after_zero_and_end_at_or_after_they_start(kind):
    """A timed boundary acts on [start, end]: end before start is an interval of no time (refused), a negative start
    too; start = end (an instant) passes.
    Bugs tried: `_Checker.interval` as `0 <= start` (intervals that end before they start accepted), as
    `0 <= start < end` (an instant refused); each fails here."""

    def make(start, end):
        if kind == "cuboid":
            return CuboidBoundary(lower=(0.1,) * 3, upper=(0.2,) * 3, start=start, end=end)
        if kind == "sphere":
            return SphereBoundary(radius=0.05, start=start, end=end)
        return ParticleRegion(lower=(0.1,) * 3, upper=(0.2,) * 3, start=start, end=end)

    fails(scene(boundaries=[make(0.5, 0.4)]), "sim.boundaries[0].start")
    fails(scene(boundaries=[make(-0.1, 0.4)]), "sim.boundaries[0].start")
    validate(scene(boundaries=[make(0.4, 0.4)]), "t")


def cell(params, cell_id="0123456789ab"):
    return Cell(index=0, id=cell_id, kind="accuracy", params=params, info={}, labels=("t",))


def test_a_cached_row_is_reused_only_for_the_same_cell_parameters(tmp_path):
    """A cache file is named by the cell's id, but the id is a 12-digit hash prefix and the cell definition may
    change: a row is reused only when the file's id and canonical parameters both equal the cell's; otherwise the
    cell runs again (`load` gives None), never a misread row.
    Bugs tried: `load` without the parameters check (a cached row reused without checking the cell's parameters),
    without the id check; each fails here."""
    mine = cell({"case": "drop", "cells": 16})
    row = {"status": "failed", "device": "cpu", "error": 0.1}  # a row the strict reader takes (cache.check_row)
    cache.store(tmp_path, mine, row)
    assert cache.load(tmp_path, mine) == row
    assert cache.load(tmp_path, cell({"case": "drop", "cells": 32})) is None, "same id, other parameters"
    other = cell({"case": "drop", "cells": 16}, cell_id="ba9876543210")
    cache.cache_path(tmp_path, other.id).write_text(cache.cache_path(tmp_path, mine.id).read_text())
    assert cache.load(tmp_path, other) is None, "a file holding another cell's id"


def test_a_cached_row_is_reused_only_on_the_same_device_type(tmp_path):
    """`scan` reuses a row only from a run on the same device type: a CPU row is not a GPU result (its wall time
    would mix into the GPU's speed-vs-error) nor the reverse; `cuda:1` is the type `cuda`; a row without a device
    was written by the CPU.
    Bugs tried: `scan` without the device check (a cached row reused on another device), comparing the full device
    string (`cuda:1` ≠ `cuda`), defaulting a missing device to `cuda`; each fails here."""
    cells = [cell({"n": i}, cell_id=f"{i:012x}") for i in range(4)]
    rows = [{"status": "failed", "device": d} for d in ("cpu", "cuda:1", "cuda")] + [{"status": "failed"}]
    for c, r in zip(cells, rows):
        cache.store(tmp_path, c, r)
    assert sorted(cache.scan(tmp_path, cells, "cpu")) == [cells[0].id, cells[3].id]
    assert sorted(cache.scan(tmp_path, cells, "cuda")) == [cells[1].id, cells[2].id]
