"""Topologies shared between variants that run at the same time: on different devices (`FileChannel`,
worker processes) or at once on one device (`MemoryChannel`, threads).

The leader variant runs the event provider; after each of its frames it publishes what latched
(`FileChannel.publish`: a file per frame, so followers in other processes see it). A follower, at
the end of its own frame f, waits until the leader has finished frame f and latches whatever the
leader latched up to then — the replay of `ReplayProvider`, live instead of from a finished run.
Before the first latch every variant runs the shared field, so leader and followers reach each frame
in the same state.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Optional

import torch

from ..topology import Topology
from .replay import ReplayProvider


class FileChannel:
    """The leader's topologies, frame by frame, for followers in other processes: `frame_NNNNNN.pt`
    (the frame's latched Topology on the CPU, or None) written by tmp + rename, `closed` when the
    leader stops. Any process (or thread) that sees the folder can follow."""

    def __init__(self, folder: Path, timeout: float = 3600.0, poll: float = 0.002):
        self.folder, self.timeout, self.poll = Path(folder), timeout, poll
        self.folder.mkdir(parents=True, exist_ok=True)
        self.seen: dict[int, Optional[Topology]] = {}

    def _path(self, frame: int) -> Path:
        return self.folder / f"frame_{frame:06d}.pt"

    def publish(self, frame: int, topology: Optional[Topology]) -> None:
        if topology is not None:
            topology = replace(topology, fragment=topology.fragment.cpu(), band=topology.band.cpu())
        tmp = self.folder / f".frame_{frame:06d}.{os.getpid()}.tmp"
        torch.save(topology, tmp)
        os.replace(tmp, self._path(frame))

    def close(self) -> None:
        (self.folder / "closed").touch()

    def first(self) -> Optional[Topology]:
        """The first topology the leader latched so far (None before its first latch), without waiting."""
        self._read()
        return next((t for _, t in sorted(self.seen.items()) if t is not None), None)

    def _read(self, frame: Optional[int] = None) -> None:
        """Load the frames published so far (up to `frame`) that this reader has not seen."""
        for path in sorted(self.folder.glob("frame_*.pt")):
            f = int(path.stem[6:])
            if (frame is None or f <= frame) and f not in self.seen:
                self.seen[f] = torch.load(path, weights_only=False)

    def up_to(self, frame: int) -> list[Topology]:
        """Everything the leader latched at frames ≤ `frame`, once it has finished that frame."""
        deadline = time.monotonic() + self.timeout
        while not self._path(frame).exists() and not (self.folder / "closed").exists():
            if time.monotonic() > deadline:
                raise TimeoutError(f"the leading variant did not reach frame {frame} within {self.timeout:.0f} s")
            time.sleep(self.poll)
        self._read(frame)
        return [t for f, t in sorted(self.seen.items()) if t is not None and f <= frame and t.latch_frame <= frame]


class MemoryChannel:
    """`FileChannel`'s contract for followers in threads of the leader's process: the frame's latched
    Topology (on the CPU, so a follower copies it onto its own stream) kept in memory, a condition variable
    instead of polling."""

    def __init__(self, timeout: float = 3600.0):
        self.timeout = timeout
        self.frames: dict[int, Optional[Topology]] = {}
        self.closed = False
        self._changed = threading.Condition()

    def publish(self, frame: int, topology: Optional[Topology]) -> None:
        if topology is not None:
            topology = replace(topology, fragment=topology.fragment.cpu(), band=topology.band.cpu())
        with self._changed:
            self.frames[frame] = topology
            self._changed.notify_all()

    def close(self) -> None:
        with self._changed:
            self.closed = True
            self._changed.notify_all()

    def first(self) -> Optional[Topology]:
        """The first topology the leader latched so far (None before its first latch)."""
        with self._changed:
            latched = [t for _, t in sorted(self.frames.items()) if t is not None]
        return latched[0] if latched else None

    def up_to(self, frame: int) -> list[Topology]:
        """Everything the leader latched at frames ≤ `frame`, once it has finished that frame."""
        with self._changed:
            if not self._changed.wait_for(lambda: frame in self.frames or self.closed, timeout=self.timeout):
                raise TimeoutError(f"the leading variant did not reach frame {frame} within {self.timeout:.0f} s")
            return [
                t for f, t in sorted(self.frames.items()) if t is not None and f <= frame and t.latch_frame <= frame
            ]


class LeaderProvider:
    """Wraps the leader's event provider and publishes every frame's outcome."""

    def __init__(self, provider, channel):
        self.provider, self.channel = provider, channel

    def __call__(self, sim) -> Optional[Topology]:
        topology = self.provider(sim) if self.provider is not None else None
        self.channel.publish(sim.frame, topology)
        return topology


class BroadcastProvider(ReplayProvider):
    """A follower: replays the leader's topologies as the leader latches them."""

    def __init__(self, channel):
        super().__init__([])
        self.channel = channel

    def __call__(self, sim) -> Optional[Topology]:
        self.history = self.channel.up_to(sim.frame)
        return super().__call__(sim)
