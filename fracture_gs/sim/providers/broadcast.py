"""Topologies shared between variants that run at the same time on different devices.

The leader variant runs the event provider; after each of its frames it publishes what latched
(`TopologyChannel.publish`). A follower, at the end of its own frame f, waits until the leader has
finished frame f and latches whatever the leader latched up to then — the replay of
`ReplayProvider`, live instead of from a finished run. Before the first latch every variant runs
the shared field, so leader and followers reach each frame in the same state.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from typing import Optional

from ..topology import Topology
from .replay import ReplayProvider


class TopologyChannel:
    """The leader's topologies, frame by frame, for followers on other threads."""

    def __init__(self, timeout: float = 3600.0):
        self.cond = threading.Condition()
        self.history: list[Topology] = []
        self.frame = -1  # the last frame the leader has finished (and published)
        self.closed = False  # the leader stopped (finished, diverged or interrupted)
        self.timeout = timeout

    def publish(self, frame: int, topology: Optional[Topology]) -> None:
        with self.cond:
            if topology is not None:
                self.history.append(replace(topology, fragment=topology.fragment.cpu(), band=topology.band.cpu()))
            self.frame = max(self.frame, frame)
            self.cond.notify_all()

    def close(self) -> None:
        with self.cond:
            self.closed = True
            self.cond.notify_all()

    def up_to(self, frame: int) -> list[Topology]:
        """Everything the leader latched at frames ≤ `frame`, once it has finished that frame."""
        with self.cond:
            if not self.cond.wait_for(lambda: self.frame >= frame or self.closed, timeout=self.timeout):
                raise TimeoutError(f"the leading variant did not reach frame {frame} within {self.timeout:.0f} s")
            return [t for t in self.history if t.latch_frame <= frame]


class LeaderProvider:
    """Wraps the leader's event provider and publishes every frame's outcome."""

    def __init__(self, provider, channel: TopologyChannel):
        self.provider, self.channel = provider, channel

    def __call__(self, sim) -> Optional[Topology]:
        topology = self.provider(sim) if self.provider is not None else None
        self.channel.publish(sim.frame, topology)
        return topology


class BroadcastProvider(ReplayProvider):
    """A follower: replays the leader's topologies as the leader latches them."""

    def __init__(self, channel: TopologyChannel):
        super().__init__([])
        self.channel = channel

    def __call__(self, sim) -> Optional[Topology]:
        self.history = self.channel.up_to(sim.frame)
        return super().__call__(sim)
