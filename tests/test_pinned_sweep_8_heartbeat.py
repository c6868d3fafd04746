"""Pinned rules of the sweep's heartbeat (`fracture_gs.sweep.distributed.StoreCoordinator`): a rank's silence is
counted from the watcher's first read of its counter, whatever value the counter already holds and however late
that first read comes; and the documented defaults (a beat every 2 s, dead after 300 s of silence: docs/scaling.md)
are the same whichever way a coordinator is made.

Unit-level: the heartbeat loop runs on the test's thread against a scripted clock and an in-memory store; no
process group is made.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from test_pinned_sweep import coordinator
from test_pinned_sweep_3_distributed import Steps, scripted_clock

from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.driver import SweepOptions


@pytest.mark.parametrize("beats_before", [0, 1, 2, 7])
def test_silence_is_counted_from_the_first_read_of_a_counter(monkeypatch, beats_before):
    """Rank 0's loop starts at t = 0 but its first round only reads at t = 100 s (a slow first store call). Rank 1,
    whose counter already stands at `beats_before` and never moves again, is alive at 105 s and at 110 s (silent
    for exactly the 10 s timeout since that first read) and dead at 110.5 s; the 100 s before the first read are
    never counted as silence, whatever the counter held."""
    coord = coordinator(0, 2, timeout_s=10.0)
    if beats_before:
        coord.store.add(coord._key("beat", 1), beats_before)
    scripted_clock(monkeypatch, [0.0, 100.0, 105.0, 110.0, 110.5])
    coord._stop = Steps(coord, 4)
    coord._heartbeat()
    assert coord._stop.seen == [{}, {}, {}, {1: "sent no heartbeat for 10 s (it died or hangs)"}]


def test_each_watched_rank_has_its_own_first_read(monkeypatch):
    """With three ranks, rank 0 watches 1 and 2: rank 1 (counter at 1 before the first read) and rank 2 (counter
    at 0) both get their silence counted from t = 50 s, so neither is dead at 55 s, and both are at 60.5 s."""
    coord = coordinator(0, 3, timeout_s=10.0)
    coord.store.add(coord._key("beat", 1), 1)
    scripted_clock(monkeypatch, [0.0, 0.0, 50.0, 55.0, 60.5])
    coord._stop = Steps(coord, 3)
    coord._heartbeat()
    why = "sent no heartbeat for 10 s (it died or hangs)"
    assert coord._stop.seen == [{}, {}, {1: why, 2: why}]


def test_the_documented_heartbeat_defaults_hold_for_every_way_of_making_a_coordinator():
    """docs/scaling.md: a beat every 2 s, a rank dead after 300 s without one (--rank-timeout's default). The
    sweep's options, the `coordinator` factory and a StoreCoordinator made directly all default to these."""
    options = SweepOptions(out_dir=Path("out"))
    assert (options.beat_s, options.rank_timeout_s) == (2.0, 300.0)
    launch = D.Launch(0, 2, 0, 2, "h:1")
    made = D.coordinator(launch, "cpu")
    assert isinstance(made, D.StoreCoordinator) and (made.beat_s, made.timeout_s) == (2.0, 300.0)
    direct = D.StoreCoordinator(launch, "cpu")
    assert (direct.beat_s, direct.timeout_s) == (2.0, 300.0)
    assert direct.store is None and direct.dead == {}  # nothing connects before `with`
