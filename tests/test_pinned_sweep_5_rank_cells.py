"""Pinned rules of a rank running its share of a sweep (`sweep.driver._run_mine`), round five:

- on a CPU device each cell runs with one intra-op torch thread (cells on a CPU rank are many small runs, and
  ranks or threads of other ranks share the cores); on a CUDA device the thread count is left as it is;
- either way the count before the call is back afterwards, also when a cell raises;
- cells run in the order given, each one's row is cached as it finishes and returned under its id, the shared
  `done` counter counts them, and each prints one progress line: the rank's tag, k/n of this rank, the
  cell's place in the whole sweep, its id, its description and its result;
- a rank with no cells does nothing (no warm-up, no thread change).

The cell runner and the cache writer are replaced by recorders: nothing is simulated (no GPU is needed to take
the CUDA path, which only reads the device's name).
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from fracture_gs.sweep import driver
from fracture_gs.sweep.distributed import Launch
from fracture_gs.sweep.expansion import Cell

BEFORE = 2  # the thread count set before each call (the machine has at least two cores)


def cell(i: int) -> Cell:
    info = {"config": "bread", "variant": "full", "seed": i}
    return Cell(i, f"{i:012x}", "scene", {"kind": "scene", "i": i}, info, ("t",))


@pytest.fixture
def threads():
    """BEFORE threads during the test; the count found before it comes back after."""
    found = torch.get_num_threads()
    torch.set_num_threads(BEFORE)
    yield
    torch.set_num_threads(found)


@pytest.fixture
def recorded(monkeypatch):
    """run_one returns an ok row whose time is the thread count it ran with; cache.store records what it got."""
    seen = SimpleNamespace(ran=[], stored=[], warm=[])

    def run_one(c, launch, device, out):
        seen.ran.append((c.id, torch.get_num_threads()))
        return {**driver.base_row(c), "status": "ok", "cell_s": float(torch.get_num_threads())}

    monkeypatch.setattr(driver, "run_one", run_one)
    monkeypatch.setattr(driver.cache, "store", lambda out, c, row: seen.stored.append((out, c.id, row)))
    monkeypatch.setattr(driver, "warmup", lambda device: seen.warm.append((device, torch.get_num_threads())))
    return seen


def run(mine, device, tmp_path, warmup=False, total=10, done=None):
    lines = []
    done = [0] if done is None else done
    rows = driver._run_mine(
        SimpleNamespace(warmup=warmup), mine, total, Launch(1, 3), device, tmp_path, lines.append, done
    )
    return rows, lines, done


@pytest.mark.parametrize("device", ["cpu", "cpu:0"])
def test_a_cpu_rank_runs_each_cell_and_its_warm_up_on_one_thread_and_restores_the_count(
    threads, recorded, tmp_path, device
):
    """On a CPU device the warm-up and both cells see one torch thread; the count is BEFORE again afterwards."""
    rows, _, _ = run([cell(4), cell(7)], device, tmp_path, warmup=True)
    assert recorded.warm == [(device, 1)]
    assert recorded.ran == [(cell(4).id, 1), (cell(7).id, 1)]
    assert torch.get_num_threads() == BEFORE


@pytest.mark.parametrize("device", ["cuda", "cuda:1"])
def test_a_cuda_rank_leaves_the_thread_count_alone(threads, recorded, tmp_path, device):
    """On a CUDA device the cells run with the thread count the process had (BEFORE), unchanged after."""
    run([cell(4), cell(7)], device, tmp_path, warmup=True)
    assert recorded.warm == [(device, BEFORE)]
    assert recorded.ran == [(cell(4).id, BEFORE), (cell(7).id, BEFORE)]
    assert torch.get_num_threads() == BEFORE


def test_a_cell_that_raises_still_restores_the_thread_count(threads, monkeypatch, tmp_path):
    """An exception out of a cell (an interrupt, say) propagates, and the thread count is BEFORE again."""

    def boom(c, launch, device, out):
        assert torch.get_num_threads() == 1
        raise KeyboardInterrupt

    monkeypatch.setattr(driver, "run_one", boom)
    with pytest.raises(KeyboardInterrupt):
        run([cell(0)], "cpu", tmp_path)
    assert torch.get_num_threads() == BEFORE


def test_cells_run_in_order_are_cached_counted_and_reported(threads, recorded, tmp_path):
    """Two cells (the 5th and 8th of 10 in the sweep) on rank 1 of 3: rows come back under their ids in order,
    each row is cached in the output folder as it is, `done` goes from 3 (other work already counted) to 5,
    and the progress lines read `[rank 1/3] k/2 cell i/10 <id> <description>: ok <s> s`."""
    done = [3]
    rows, lines, done = run([cell(4), cell(7)], "cpu", tmp_path, done=done)
    assert list(rows) == [cell(4).id, cell(7).id]
    assert [r["index"] for r in rows.values()] == [4, 7]
    assert recorded.stored == [(tmp_path, c.id, rows[c.id]) for c in (cell(4), cell(7))]
    assert done == [5]
    assert lines == [
        f"[rank 1/3] 1/2 cell 5/10 {cell(4).id} bread full seed 4: ok 1.0 s",
        f"[rank 1/3] 2/2 cell 8/10 {cell(7).id} bread full seed 7: ok 1.0 s",
    ]


def test_a_rank_without_cells_does_nothing(threads, recorded, tmp_path):
    """No cells: an empty result, no warm-up (even when the spec asks), no line, nothing counted, and the
    thread count untouched."""
    rows, lines, done = run([], "cpu", tmp_path, warmup=True)
    assert rows == {} and lines == [] and done == [0]
    assert recorded.warm == [] and recorded.ran == [] and recorded.stored == []
    assert torch.get_num_threads() == BEFORE
