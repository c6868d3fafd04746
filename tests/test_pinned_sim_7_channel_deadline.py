"""`FileChannel.up_to` (sim/providers/broadcast.py) waits at least its timeout: on a clock that moves one poll at a
time, a follower keeps polling while the clock reads at or before start + timeout and gives up with a
TimeoutError naming the frame and the timeout only once the clock has passed it, so a leader that publishes the
frame during the poll that starts exactly at the deadline is still followed. A frame already there, or a closed
channel, returns without sleeping."""

from __future__ import annotations

import types

import pytest
import torch

from fracture_gs.sim.providers import broadcast
from fracture_gs.sim.providers.broadcast import FileChannel
from fracture_gs.sim.topology import Topology

TOPO = Topology(torch.tensor([0, 1]), torch.tensor([0, 0]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=1)


class Clock:
    """A fake `time` for broadcast: monotonic() reads `now`; sleep(s) advances it by s and runs the leader's action
    scheduled for the sleep that starts at that reading."""

    def __init__(self, start: float, actions=None):
        self.now, self.actions, self.sleeps = start, dict(actions or {}), []

    def monotonic(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.sleeps.append(self.now)
        action = self.actions.pop(self.now, None)
        self.now += s
        if action:
            action()


def follow(monkeypatch, tmp_path, clock: Clock, frame: int = 1):
    monkeypatch.setattr(broadcast, "time", types.SimpleNamespace(monotonic=clock.monotonic, sleep=clock.sleep))
    return FileChannel(tmp_path, timeout=3.0, poll=1.0).up_to(frame)


def test_a_frame_published_in_the_poll_at_the_deadline_is_followed(tmp_path, monkeypatch):
    """Start 100 s, timeout 3 s, poll 1 s: the leader publishes frame 1 during the poll that starts at 103 s (the
    deadline itself); the follower sees it and returns its topology, after polls at 100, 101, 102 and 103 s."""
    leader = FileChannel(tmp_path)
    clock = Clock(100.0, {103.0: lambda: leader.publish(1, TOPO)})
    got = follow(monkeypatch, tmp_path, clock)
    assert [t.latch_frame for t in got] == [1]
    assert clock.sleeps == [100.0, 101.0, 102.0, 103.0]


def test_a_leader_that_never_comes_times_out_just_past_the_deadline(tmp_path, monkeypatch):
    """With no leader the follower polls at 100 … 103 s and raises at 104 s, the first reading past 103 s, with one
    sentence naming the frame and the timeout."""
    clock = Clock(100.0)
    with pytest.raises(TimeoutError) as info:
        follow(monkeypatch, tmp_path, clock, frame=7)
    assert str(info.value) == "the leading variant did not reach frame 7 within 3 s"
    assert clock.sleeps == [100.0, 101.0, 102.0, 103.0] and clock.now == 104.0


def test_a_frame_already_there_or_a_closed_channel_returns_without_waiting(tmp_path, monkeypatch):
    """A frame the leader already published, or any frame once the leader closed the channel, returns at once:
    no poll at all."""
    leader = FileChannel(tmp_path)
    leader.publish(1, TOPO)
    clock = Clock(100.0)
    assert [t.latch_frame for t in follow(monkeypatch, tmp_path, clock, frame=1)] == [1]
    leader.close()
    assert [t.latch_frame for t in follow(monkeypatch, tmp_path, clock, frame=9)] == [1]
    assert clock.sleeps == []
