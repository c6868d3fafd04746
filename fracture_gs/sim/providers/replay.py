"""Replay provider: latches a saved topology at its recorded frame, so every variant of a run uses the
same fragments (the first variant's provider decided them; `topology.npz` holds them)."""
from __future__ import annotations

from typing import Optional

from ..topology import Topology


class ReplayProvider:
    """Latches a saved topology at its recorded frame (labels identical across variants)."""

    def __init__(self, topology: Topology):
        self.topology = topology
        self.done = False

    def __call__(self, sim) -> Optional[Topology]:
        if self.done or sim.frame < self.topology.latch_frame:
            return None
        self.done = True
        t = self.topology
        return Topology(fragment=t.fragment.to(sim.device), band=t.band.to(sim.device), normal=t.normal, point=t.point,
                        latch_time=sim.time, latch_frame=sim.frame, pair_radius=t.pair_radius)
