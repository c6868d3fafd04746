"""StoreCoordinator.close (issue 34, mutation round 12): it stops the heartbeat thread at once, waits for a thread
stuck in a store call for at most one beat plus five seconds (then leaves the daemon thread behind), and destroys
the process group only when one is up and no rank failed. Unit-level: no process group is formed."""

from __future__ import annotations

import threading
import time

import pytest
import torch.distributed as dist

from fracture_gs.sweep.distributed import Launch, StoreCoordinator


class _StuckThread:
    """A heartbeat thread stuck in a store call: records each join's timeout and never finishes."""

    def __init__(self):
        self.timeouts: list = []

    def join(self, timeout=None):
        self.timeouts.append(timeout)

    def is_alive(self) -> bool:
        return True


def _coord(beat_s: float) -> StoreCoordinator:
    return StoreCoordinator(
        Launch(rank=0, world_size=2, local_rank=0, local_world_size=2, master="h:1"), "cpu", 30.0, beat_s
    )


@pytest.mark.parametrize("beat_s", [0.5, 2.0, 7.25])
def test_a_stuck_heartbeat_delays_the_shutdown_by_one_beat_plus_five_seconds(monkeypatch, beat_s):
    """Rule: close sets the stop flag, then joins the heartbeat thread with a bounded wait of beat_s + 5 s (a store
    call in flight gets one beat plus five seconds to finish; a store that never answers cannot hang the
    shutdown). Exactly one join, never unbounded (None) and never zero."""
    monkeypatch.setattr(dist, "is_initialized", lambda: False)
    c = _coord(beat_s)
    c._thread = stuck = _StuckThread()
    c.close()
    assert c._stop.is_set()
    assert stuck.timeouts == [pytest.approx(beat_s + 5.0, abs=1e-9)]


def test_a_live_heartbeat_stops_at_once_on_close(monkeypatch):
    """Rule: the heartbeat waits on the stop flag between beats, so close returns at once (far below one 30 s
    beat) and the thread has ended."""
    monkeypatch.setattr(dist, "is_initialized", lambda: False)
    c = _coord(30.0)
    c._thread = threading.Thread(target=lambda: c._stop.wait(c.beat_s), daemon=True)
    c._thread.start()
    t0 = time.monotonic()
    c.close()
    assert time.monotonic() - t0 < 2.0 and not c._thread.is_alive()


@pytest.mark.parametrize(
    "initialized, failed, dead, destroys",
    [(True, False, {}, 1), (True, True, {}, 0), (True, False, {1: "gone"}, 0), (False, False, {}, 0)],
    ids=["healthy", "failed", "a-rank-dead", "no-group"],
)
def test_the_group_is_destroyed_only_when_up_and_every_rank_lived(monkeypatch, initialized, failed, dead, destroys):
    """Rule: destroy_process_group is a collective teardown: called once when a group is up and no rank failed or
    died; skipped after a failure (it would wait on the dead rank) and when no group was formed."""
    calls = []
    monkeypatch.setattr(dist, "is_initialized", lambda: initialized)
    monkeypatch.setattr(dist, "destroy_process_group", lambda *a, **k: calls.append(1))
    c = _coord(1.0)
    c._failed, c.dead = failed, dict(dead)
    c.close()
    assert len(calls) == destroys
