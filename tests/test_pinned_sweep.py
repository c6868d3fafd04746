"""Pinned rules of the sweep package (`fracture_gs.sweep`): the cache file's atomic write and JSON conversion,
cost estimates, the progress description, csv/json outputs, the row of one cell, the launch environment and
the store protocol between ranks (run against an in-memory store, no process group).

Unit-level calls only: no cell is simulated.
"""

from __future__ import annotations

import json
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from fracture_gs.config import SceneConfig
from fracture_gs.sweep import cache, driver
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.cells import Outcome
from fracture_gs.sweep.expansion import Cell, accuracy_cost, scene_cost
from fracture_gs.sweep.report import accuracy_results, csv_text, write_outputs
from fracture_gs.sweep.spec import SceneBlock, load_spec


def cell(i=0, kind="scene", params=None, **info) -> Cell:
    params = params if params is not None else {"kind": kind, "i": i}
    return Cell(i, f"{i:012x}", kind, params, info or {"config": "bread", "variant": "full", "seed": 0}, ("t",))


# ---------------------------------------------------------------------------------------------
# cache files


def test_unserializable_payload_raises_typeerror_and_leaves_no_file(tmp_path):
    """A cache payload holding something JSON cannot hold raises TypeError naming its type, and leaves neither
    the target file nor a temporary file behind (the atomic write cleans up after itself)."""
    path = tmp_path / "cells" / "abc.json"
    with pytest.raises(TypeError, match="object"):
        cache.write_json_atomic(path, {"row": {"x": object()}})
    assert list(path.parent.iterdir()) == []


def test_an_earlier_file_survives_a_failed_rewrite(tmp_path):
    """When rewriting a cache file fails, the previous file is kept whole."""
    path = tmp_path / "a.json"
    cache.write_json_atomic(path, {"v": 1})
    with pytest.raises(TypeError):
        cache.write_json_atomic(path, {"v": object()})
    assert json.loads(path.read_text()) == {"v": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


class ItemOnly:
    """A scalar-like object with `.item()` but no `.tolist()`."""

    def item(self):
        return 2.5


def test_numpy_and_torch_values_are_written_as_plain_json(tmp_path):
    """Arrays and tensors are written as (nested) lists, numpy/torch scalars and anything with .item() as
    numbers, so a row of a run reads back as plain JSON."""
    path = tmp_path / "r.json"
    row = {
        "a": np.arange(3),
        "t": torch.tensor([[1.0, 2.0], [3.0, 4.0]]),
        "f32": np.float32(0.5),
        "i64": np.int64(7),
        "t0": torch.tensor(1.5),
        "it": ItemOnly(),
    }
    cache.write_json_atomic(path, row)
    assert json.loads(path.read_text()) == {
        "a": [0, 1, 2],
        "t": [[1.0, 2.0], [3.0, 4.0]],
        "f32": 0.5,
        "i64": 7,
        "t0": 1.5,
        "it": 2.5,
    }


def test_cache_rows_are_reused_only_for_the_same_cell_and_device_type(tmp_path):
    """A cached row is reused for the cell with the same id and parameters, by a run on the same device type
    (cuda:1 counts as cuda; a row without a device as cpu); a file whose parameters differ is ignored (the cell
    runs again), and a file that is not a JSON object, or whose row is not a table, is refused naming the file."""
    from fracture_gs.errors import OutputError

    a, b, c, d = cell(0), cell(1), cell(2), cell(3)
    cache.store(tmp_path, a, {"status": "ok", "device": "cuda:1"})
    cache.store(tmp_path, b, {"status": "ok"})
    cache.store(tmp_path, cell(2, params={"kind": "scene", "i": 99}), {"status": "ok"})  # same id, other params
    cache.cache_path(tmp_path, d.id).write_text("[1, 2]")
    e = cell(4)
    cache.write_json_atomic(cache.cache_path(tmp_path, e.id), {"id": e.id, "params": e.params, "row": [1, 2]})
    assert cache.load(tmp_path, a) == {"status": "ok", "device": "cuda:1"}
    assert cache.load(tmp_path, c) is None
    for damaged in (d, e):
        with pytest.raises(OutputError, match=damaged.id):
            cache.load(tmp_path, damaged)
    assert set(cache.scan(tmp_path, [a, b, c], "cuda")) == {a.id}
    assert set(cache.scan(tmp_path, [a, b, c], "cpu")) == {b.id}
    assert cache.scan(tmp_path / "nowhere", [a], "cpu") == {}


# ---------------------------------------------------------------------------------------------
# cost estimates


def scene(adaptive=False, E=2000.0, dt=1e-3, frames=10, particles=1000, dx=0.02, cfl=0.4):
    cfg = SceneConfig()
    cfg.material.E, cfg.material.nu, cfg.material.density = E, 0.3, 200.0
    cfg.sim.adaptive_dt, cfg.sim.dt, cfg.sim.dx, cfg.sim.cfl = adaptive, dt, dx, cfl
    cfg.frames, cfg.frame_dt, cfg.particles = frames, 0.01, particles
    return cfg


def test_adaptive_scene_costs_what_its_cfl_step_costs():
    """An adaptive-Δt cell is estimated at the CFL step cfl·Δx/c of its material (c the P-wave speed): the same
    cost as a fixed-Δt cell at that step; four times the stiffness doubles c and the substeps, so the cost
    grows; a fixed step shorter than the CFL bound wins."""
    c = (2000.0 * 0.7 / (200.0 * 1.3 * 0.4)) ** 0.5  # ≈ 3.67 m/s: the CFL step 0.4·0.02/c ≈ 2.2 ms > dt
    assert scene_cost(scene(adaptive=True)) == pytest.approx(scene_cost(scene(dt=1e-3)))
    stiff = 2000.0 * 400  # c × 20: the CFL step (≈ 0.11 ms) binds
    step = 0.4 * 0.02 / (20 * c)
    assert scene_cost(scene(adaptive=True, E=stiff)) == pytest.approx(scene_cost(scene(dt=step, E=stiff)), rel=1e-9)
    assert scene_cost(scene(adaptive=True, E=4 * stiff)) > 1.5 * scene_cost(scene(adaptive=True, E=stiff))
    assert scene_cost(scene(adaptive=False, E=4 * stiff)) == scene_cost(scene(adaptive=False, E=stiff))


def test_particles_double_a_substeps_cost_at_the_unit():
    """A substep's estimated time grows linearly with the particle count and doubles at PARTICLES_PER_UNIT_COST
    (200k) particles: launch-bound below, bandwidth-bound beyond."""
    from fracture_gs.sweep.expansion import PARTICLES_PER_UNIT_COST, SECONDS_PER_FRAME

    assert PARTICLES_PER_UNIT_COST == 2e5
    frame_part = 10 * SECONDS_PER_FRAME  # scene(): 10 frames
    one, unit, two = (scene_cost(scene(particles=n)) - frame_part for n in (1, 200_001, 400_001))
    assert unit == pytest.approx(2 * one, rel=1e-4)
    assert two - unit == pytest.approx(unit - one, rel=1e-9)


def test_scene_cost_is_positive_and_grows_with_the_work():
    """A scene cell's estimate is positive and grows with its frames, its substeps (shorter dt) and its
    particles; even a one-substep-per-frame cell costs something per frame."""
    base = scene_cost(scene())
    assert base > 0
    assert scene_cost(scene(frames=20)) > base
    assert scene_cost(scene(dt=5e-4)) > base
    assert scene_cost(scene(particles=100_000)) > base
    one = scene(dt=0.01)
    assert scene_cost(one) > 0 and scene_cost(scene(dt=0.01, frames=20)) > scene_cost(one)
    assert scene_cost(scene(dt=0.01 / 1.5)) > scene_cost(one)  # 1.5 substeps a frame cost more than 1


@pytest.mark.parametrize("case", ["bar", "spin", "recontact"])
def test_accuracy_cost_grows_with_resolution_and_shrinks_with_cfl(case):
    """An accuracy cell costs more at a finer grid and less at a larger CFL number (longer substeps)."""
    assert 0 < accuracy_cost(case, 16, 0.4) < accuracy_cost(case, 32, 0.4)
    assert accuracy_cost(case, 32, 0.2) > accuracy_cost(case, 32, 0.4)


# ---------------------------------------------------------------------------------------------
# cells, specs, rows


def test_scene_cell_description_names_cells_only_when_set():
    """A scene cell's progress line names its grid cells only when the cell sets them, then its step and
    overrides, then its seed; an accuracy cell's line names case, Δx and CFL."""
    plain = cell(0, config="bread", variant="full", cells=None, step=None, set="", seed=0)
    assert plain.describe == "bread full seed 0"
    full = cell(1, config="bread", variant="full", cells=32, step="dt=0.0001", set="material.E=5", seed=2)
    assert full.describe == "bread full cells 32 dt=0.0001 material.E=5 seed 2"
    acc = cell(2, kind="accuracy", case="bar", cells=16, cfl=0.4)
    assert acc.describe == "bar Δx=1/16 CFL 0.4"


def test_a_scene_block_renders_nothing_unless_asked():
    """A SceneBlock made in Python without `render` runs metrics only, like a [[scene]] table without it."""
    block = SceneBlock(configs=("bread",))
    assert block.render is False
    assert (block.cells, block.steps, block.seeds, block.variants) == ((None,), (None,), (0,), ())


def test_scene_spec_scalars_are_read_as_given(tmp_path):
    """A [[scene]] table's scalar frames, particles and preset are the block's values; render defaults to off."""
    path = tmp_path / "s.toml"
    path.write_text('[[scene]]\nconfig = "bread"\nframes = 7\nparticles = 500\npreset = "paper"\n')
    block = load_spec(path).scenes[0]
    assert (block.frames, block.particles, block.preset, block.render) == (7, 500, "paper", False)


@pytest.mark.parametrize(
    "key, value", [("frames", "[10, 20]"), ("particles", "[100, 200]"), ("preset", '["small", "paper"]')]
)
def test_a_scene_scalar_given_as_a_list_is_refused_by_name(tmp_path, key, value):
    """frames, particles and preset take one value per [[scene]] table: a list of two would silently keep only its
    first, so it is refused naming scene[0].<key> and the fix (one table per value)."""
    from fracture_gs.errors import ConfigError

    path = tmp_path / "s.toml"
    path.write_text(f'[[scene]]\nconfig = "bread"\n{key} = {value}\n')
    with pytest.raises(ConfigError, match=rf"scene\[0\]\.{key}.*one \[\[scene\]\] table per value"):
        load_spec(path)


def test_a_rendered_scene_cell_reports_its_one_variant(monkeypatch, tmp_path):
    """A scene cell with render = true runs render-sim for its one variant and reports that variant's summary:
    flat numbers as metrics (with the latch frame and time lifted out, particles and frames added), tables and
    lists as extras, the variant's status as the cell's."""
    import fracture_gs.render_sim as runner
    from fracture_gs.io.config import config_from_dict, config_to_dict
    from fracture_gs.render_sim import RunSummary
    from fracture_gs.sweep.cells import run_cell

    calls = []

    def fake_render_sim(cfg, variants, device, folder, progress=True):
        calls.append((list(variants), device, folder))
        latch = {"latch_frame": 4, "latch_time": 0.04}
        variant = {"variant": variants[0], "status": "diverged at frame 9: x", "opening": 1.5, "latch": latch}
        return RunSummary("c", "bread", "small", device, 321, [], 9, 0.01, [variant | {"fragments": [1, 2]}])

    monkeypatch.setattr(runner, "run_render_sim", fake_render_sim)
    config = config_to_dict(config_from_dict({"variants": ["baseline"], "frames": 9}))
    c = Cell(0, "abc", "scene", {"variant": "baseline", "seed": 0, "render": True}, {}, ("t",), config)
    out = run_cell(c, "cpu", tmp_path)
    assert calls == [(["baseline"], "cpu", tmp_path / "cells" / "abc")]
    assert out.status == "diverged at frame 9: x"
    assert out.metrics == {"opening": 1.5, "latch_frame": 4, "latch_time": 0.04, "particles": 321, "frames": 9}
    assert out.extra == {"latch": {"latch_frame": 4, "latch_time": 0.04}, "fragments": [1, 2]}


def test_run_one_times_the_cell_and_records_where_it_ran(monkeypatch):
    """A cell's row carries its metrics, status ok, and cell_s = the wall time between its start and end; a
    cell that stops early is `failed` with the reason as message; a cell that raises is `failed` with the
    exception's sentence and a traceback."""
    clock = iter([100.0, 102.5, 200.0, 200.25, 300.0, 301.0])
    monkeypatch.setattr(driver.time, "perf_counter", lambda: next(clock))
    outcomes = iter([Outcome({"error": 0.1}), Outcome({"error": 0.2}, "diverged at frame 3: x")])
    monkeypatch.setattr(driver, "run_cell", lambda c, dev, out: next(outcomes))
    launch = D.Launch()
    row = driver.run_one(cell(0), launch, "cpu", None)
    assert row["cell_s"] == pytest.approx(2.5)
    assert (row["status"], row["message"], row["error"], row["rank"], row["device"]) == ("ok", "", 0.1, 0, "cpu")
    row = driver.run_one(cell(1), launch, "cpu", None)
    assert row["cell_s"] == pytest.approx(0.25)
    assert (row["status"], row["message"]) == ("failed", "diverged at frame 3: x")

    def boom(c, dev, out):
        raise RuntimeError("out of memory")

    monkeypatch.setattr(driver, "run_cell", boom)
    row = driver.run_one(cell(2), launch, "cpu", None)
    assert row["cell_s"] == pytest.approx(1.0)
    assert (row["status"], row["message"]) == ("failed", "RuntimeError: out of memory")
    assert "RuntimeError" in row["traceback"]


# ---------------------------------------------------------------------------------------------
# outputs


ROWS = [
    {"id": "a", "kind": "scene", "status": "ok", "opening": 1.5, "latch_frame": None, "extra": {"x": 1}},
    {"id": "b", "kind": "scene", "status": "failed", "message": "boom", "flag": True, "traceback": "T"},
    {"id": "c", "kind": "scene", "status": "ok", "flag": False, "nested": [1, 2], "opening": 0.1 + 0.2},
]


def test_csv_has_every_row_and_the_union_of_keys():
    """sweep.csv: a header with the union of the row keys in first-seen order (no traceback or extra), then one
    line per row: None as empty, booleans as yes/no, floats at full precision, lists as JSON."""
    lines = csv_text(ROWS).splitlines()
    assert lines[0] == "id,kind,status,opening,latch_frame,message,flag,nested"
    assert lines[1:] == [
        "a,scene,ok,1.5,,,,",
        "b,scene,failed,,,boom,yes,",
        'c,scene,ok,0.30000000000000004,,,no,"[1, 2]"',
    ]


def test_sweep_json_holds_the_rows_and_counts(tmp_path):
    """sweep.json reads back with every row and the ok / failed / missing counts; the tables are written."""
    spec = SimpleNamespace(source="s.toml", title="T", path=tmp_path / "s.toml")
    rows = [{k: v for k, v in r.items() if k != "extra"} for r in ROWS] + [
        {"id": "d", "kind": "scene", "status": "missing"}
    ]
    files = write_outputs(tmp_path / "out", spec, rows, 2, "cmd")
    assert files == ["sweep.md", "sweep.tex", "sweep.csv", "sweep.json"]
    data = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert data["counts"] == {"ok": 2, "failed": 1, "missing": 1}
    assert data["rows"] == rows and data["world_size"] == 2 and data["command"] == "cmd"
    md = (tmp_path / "out" / "sweep.md").read_text()
    assert "failed: boom" in md and "4 cells from s.toml: 2 ok, 1 failed, 1 missing" in md


def test_accuracy_results_one_per_label_of_finished_rows():
    """Each finished accuracy row gives one Result per label it was produced under (Δx = 1/cells); failed rows
    and scene rows give none."""
    base = {"kind": "accuracy", "case": "bar", "cells": 16, "dt": 1e-4, "cfl": 0.4, "particles": 10, "substeps": 5}
    base |= {"wall_s": 1.0, "error": 0.01, "unit": "%"}
    rows = [{**base, "status": "ok", "labels": "dx+cfl"}, {**base, "status": "failed", "labels": "dx"}, ROWS[0]]
    results = accuracy_results(rows)
    assert [(r.sweep, r.dx, r.case) for r in results] == [("dx", 1 / 16, "bar"), ("cfl", 1 / 16, "bar")]


# ---------------------------------------------------------------------------------------------
# launch environment


def test_launch_environment_bounds():
    """WORLD_SIZE = 1 with RANK = 0 is a valid one-process launch (no master needed); WORLD_SIZE 0, a RANK equal
    to WORLD_SIZE, or LOCAL_WORLD_SIZE above WORLD_SIZE is a LaunchError; several ranks need MASTER_ADDR/PORT."""
    one = D.launch_from_env({"RANK": "0", "WORLD_SIZE": "1"})
    assert (one.rank, one.world_size, one.local_rank, one.local_world_size, one.distributed) == (0, 1, 0, 1, False)
    assert D.launch_from_env({}) == D.Launch()
    for env in (
        {"RANK": "0", "WORLD_SIZE": "0"},
        {
            "RANK": "2",
            "WORLD_SIZE": "2",
            "LOCAL_RANK": "0",
            "LOCAL_WORLD_SIZE": "1",
            "MASTER_ADDR": "h",
            "MASTER_PORT": "1",
        },
        {"RANK": "-1", "WORLD_SIZE": "2", "MASTER_ADDR": "h", "MASTER_PORT": "1"},
        {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_WORLD_SIZE": "2"},
        {"RANK": "0", "WORLD_SIZE": "2"},
    ):
        with pytest.raises(D.LaunchError):
            D.launch_from_env(env)
    two = D.launch_from_env({"RANK": "1", "WORLD_SIZE": "2", "MASTER_ADDR": "h", "MASTER_PORT": "1"})
    assert (two.local_rank, two.local_world_size, two.master, two.tag) == (1, 2, "h:1", "[rank 1/2]")


def test_device_flag_is_checked():
    """--device cpu is the CPU; a name that is no device, or cuda:N beyond the machine's GPUs, is a LaunchError."""
    assert D.resolve_device("cpu", D.Launch()) == "cpu"
    assert D.resolve_device(" CPU ", D.Launch()) == "cpu"
    with pytest.raises(D.LaunchError, match="not a device"):
        D.resolve_device("gpu", D.Launch())
    with pytest.raises(D.LaunchError, match="does not exist"):
        D.resolve_device(f"cuda:{torch.cuda.device_count()}", D.Launch())


# ---------------------------------------------------------------------------------------------
# the store protocol, on an in-memory store


class FakeStore:
    """The four calls of torch's TCPStore the coordinator uses, in memory and thread-safe."""

    def __init__(self):
        self.data, self.lock = {}, threading.Lock()

    def set(self, key, value):
        with self.lock:
            self.data[key] = value.encode() if isinstance(value, str) else value

    def get(self, key):
        with self.lock:
            return self.data[key]

    def check(self, keys):
        with self.lock:
            return all(k in self.data for k in keys)

    def add(self, key, n):
        with self.lock:
            value = int(self.data.get(key, b"0")) + n
            self.data[key] = str(value).encode()
            return value


def coordinator(rank, world, timeout_s=300.0, beat_s=2.0):
    launch = D.Launch(rank, world, rank, world, "h:1")
    coord = D.StoreCoordinator(launch, "cpu", timeout_s, beat_s)
    coord.store = FakeStore()
    return coord


def test_rank_zero_gathers_every_ranks_rows():
    """finish on rank 0 returns its own rows and those each other rank published; on another rank it publishes
    its rows and a done mark and returns None."""
    one = coordinator(1, 2)
    assert one.finish({"b": {"status": "ok"}}) is None
    zero = coordinator(0, 2)
    zero.store = one.store
    assert zero.finish({"a": {"status": "ok"}}) == [{"a": {"status": "ok"}}, {"b": {"status": "ok"}}]


def test_plan_is_made_on_rank_zero_from_every_ranks_cache():
    """Rank 0 waits for every rank's cached statuses, makes the plan from all of them (in rank order) and
    publishes it; another rank reads that plan."""
    zero, one = coordinator(0, 2), coordinator(1, 2)
    one.store = zero.store
    zero.store.set(zero._key("cached", 1), json.dumps({"x": "ok"}))
    seen = []
    plan = zero.plan({"y": "failed"}, lambda statuses: seen.append(statuses) or {"digest": "d", "n": len(statuses)})
    assert seen == [[{"y": "failed"}, {"x": "ok"}]] and plan == {"digest": "d", "n": 2}
    assert one.plan({}, lambda s: pytest.fail("only rank 0 plans")) == plan


def publish_later(store, pairs, delay=0.15) -> None:
    """Set the (key, value) pairs on `store` from another thread after `delay` seconds."""

    def later():
        time.sleep(delay)
        for key, value in pairs:
            store.set(key, value)

    threading.Thread(target=later, daemon=True).start()


def test_waiting_ranks_notice_a_key_within_a_fraction_of_a_second():
    """A rank waiting for another's key (rank 1 for the plan, rank 0 for a done mark) polls the store several
    times a second: it returns well under a second after the key appears."""
    one = coordinator(1, 2)
    publish_later(one.store, [(one._key("plan"), json.dumps({"p": 1}))])
    t0 = time.monotonic()
    assert one.plan({}, lambda s: None) == {"p": 1}
    assert time.monotonic() - t0 < 0.7
    zero = coordinator(0, 2)
    publish_later(zero.store, [(zero._key("rows", 1), "{}"), (zero._key("done", 1), "1")])
    t0 = time.monotonic()
    assert zero.finish({}) == [{}, {}]
    assert time.monotonic() - t0 < 0.7


def test_heartbeat_marks_a_silent_rank_dead_even_after_a_finished_one():
    """Rank 0's heartbeat watches every other rank: one that has finished (done mark) is no longer watched, and
    a later rank whose counter stops is marked dead after the timeout; a rank that keeps beating is not."""
    coord = coordinator(0, 4, timeout_s=0.05, beat_s=0.01)
    store = coord.store
    store.set(coord._key("done", 1), "1")
    stop = threading.Event()

    def beating():
        while not stop.is_set():
            store.add(coord._key("beat", 3), 1)
            time.sleep(0.005)

    threading.Thread(target=beating, daemon=True).start()
    thread = threading.Thread(target=coord._heartbeat, daemon=True)
    thread.start()
    time.sleep(0.4)
    coord._stop.set()
    stop.set()
    thread.join(2)
    assert set(coord.dead) == {2}
    assert int(store.get(coord._key("beat", 0))) > 5
    failure = coord.failure()
    assert isinstance(failure, D.RankFailure) and failure.rank == 2 and "rank 2 of 4" in str(failure)


def test_wait_on_a_dead_owner_is_a_rank_failure():
    """Waiting for a key whose owner is dead raises RankFailure naming that rank instead of waiting forever."""
    coord = coordinator(0, 2)
    coord.dead[1] = "sent no heartbeat"
    raised = []

    def plan():
        try:
            coord.plan({}, lambda s: {})
        except D.RankFailure as exc:
            raised.append(exc)

    thread = threading.Thread(target=plan, daemon=True)  # a wait that never ends fails here, not hangs
    thread.start()
    thread.join(2.0)
    assert len(raised) == 1, "the wait did not end"
    assert raised[0].rank == 1 and "rank 1 of 2 sent no heartbeat" in str(raised[0])
    assert coord.store.check([coord._key("abort")])
