"""Replay provider: latches a saved history of topologies, each at its recorded frame, so every variant
of a run uses the same fragments (the first variant's provider decided them; `topology.npz` holds
every snapshot)."""

from __future__ import annotations

from dataclasses import replace
from typing import Optional, Union

from ..topology import Topology


class ReplayProvider:
    """Returns snapshot i of the history at the first frame end ≥ its latch frame."""

    def __init__(self, history: Union[Topology, list]):
        self.history = [history] if isinstance(history, Topology) else list(history)
        self.next = 0

    @property
    def topology(self) -> Topology:
        return self.history[-1]

    def __call__(self, sim) -> Optional[Topology]:
        out = None
        while self.next < len(self.history) and sim.frame >= self.history[self.next].latch_frame:
            out = self.history[self.next]
            self.next += 1
        if out is None:
            return None
        return replace(
            out,
            fragment=out.fragment.to(sim.device),
            band=out.band.to(sim.device),
            latch_time=sim.time,
            latch_frame=sim.frame,
        )
