"""Pinned rule of the sweep driver's SIGTERM note (`fracture_gs.sweep.driver.run_sweep`): the note ("stopped by
signal ..., the cells this rank finished are cached") is installed only for a distributed launch (torchrun stops
every rank with SIGTERM when one fails) and only from the main thread (Python allows signal handlers nowhere
else). A one-process sweep leaves SIGTERM to the program that called it, and a distributed sweep driven from a
worker thread runs without touching signals.

Unit-level calls only: no cell runs (`run_one` is replaced) and the coordinator of the distributed case is a
fake (no process group).
"""

from __future__ import annotations

import signal
import threading

import pytest

from fracture_gs.sweep import distributed as D
from fracture_gs.sweep import driver

SPEC = '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16, 32]\ncfl = 0.4\n'
DONE = {"dt": 1e-4, "particles": 8, "substeps": 10, "wall_s": 1.0, "error": 0.25, "unit": "%"}


class FakeCoordinator:
    """Rank 1 of 2 as it sees rank 0: the real make_plan over (rank 0: nothing cached, rank 1: this rank)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def plan(self, cached, make_plan):
        return make_plan([{}, cached])

    def finish(self, rows):
        return None


@pytest.fixture
def sweep(tmp_path, monkeypatch):
    """A two-cell bar spec; run_one is a fake that records the SIGTERM handler in place while each cell runs."""
    (tmp_path / "s.toml").write_text(SPEC)
    monkeypatch.setattr(driver, "resolve_device", lambda flag, launch: "cpu")
    monkeypatch.setattr(driver, "warmup", lambda device: None)
    handlers = []

    def run_one(cell, launch, device, out_dir):
        handlers.append(signal.getsignal(signal.SIGTERM))
        return {**driver.base_row(cell), "status": "ok", "cell_s": 0.5, "device": device, **DONE}

    monkeypatch.setattr(driver, "run_one", run_one)
    return tmp_path / "s.toml", tmp_path / "out", handlers


def sentinel(signum, frame):
    """The caller's own SIGTERM handler (never called)."""


def test_a_one_process_sweep_leaves_sigterm_to_its_caller(sweep, monkeypatch):
    """One process (no torchrun variables): while its cells run, SIGTERM is still the caller's handler, and it is
    the caller's afterwards; the sweep ran both cells and wrote its tables."""
    spec, out, handlers = sweep
    monkeypatch.setattr(driver, "launch_from_env", lambda: D.Launch())
    before = signal.signal(signal.SIGTERM, sentinel)
    try:
        report = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lambda s: None))
        assert handlers == [sentinel, sentinel]
        assert signal.getsignal(signal.SIGTERM) is sentinel
    finally:
        signal.signal(signal.SIGTERM, before)
    assert (report.world_size, report.ran, [r["status"] for r in report.rows]) == (1, 2, ["ok", "ok"])


def test_a_distributed_sweep_installs_its_note_only_from_the_main_thread(sweep, monkeypatch):
    """Rank 1 of 2 driven from a worker thread runs its cells with the caller's SIGTERM handler untouched and
    raises nothing (signal.signal would refuse a non-main thread); the same rank on the main thread has the note
    in place while its cells run and restores the caller's handler afterwards."""
    spec, out, handlers = sweep
    monkeypatch.setattr(driver, "launch_from_env", lambda: D.Launch(1, 2, 1, 2, "h:1"))
    monkeypatch.setattr(driver, "coordinator", lambda launch, device, timeout, beat: FakeCoordinator())
    opts = driver.SweepOptions(out_dir=out, device="cpu", fresh=True, echo=lambda s: None)
    before = signal.signal(signal.SIGTERM, sentinel)
    try:
        outcome = []
        worker = threading.Thread(target=lambda: outcome.append(_run(spec, opts)))
        worker.start()
        worker.join(timeout=60)
        assert outcome == [("ran", 1)]  # the plan deals 1/32 to rank 0 and 1/16 here
        assert handlers == [sentinel]
        handlers.clear()
        assert driver.run_sweep(spec, opts).ran == 1
        assert len(handlers) == 1 and handlers[0] is not sentinel and callable(handlers[0])
        assert signal.getsignal(signal.SIGTERM) is sentinel
    finally:
        signal.signal(signal.SIGTERM, before)


def _run(spec, opts):
    try:
        return ("ran", driver.run_sweep(spec, opts).ran)
    except Exception as exc:  # noqa: BLE001 - the test reports what the thread raised
        return ("raised", repr(exc))
