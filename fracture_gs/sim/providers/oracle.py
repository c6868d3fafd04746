"""Oracle provider: an analytic plane from the config, latched at a configured frame or time."""
from __future__ import annotations

from typing import Optional

from ...config import TopologyConfig
from ..topology import Topology


class OracleProvider:
    """Latches an analytic plane from the config at a configured frame or time."""

    def __init__(self, cfg: TopologyConfig):
        self.cfg = cfg
        self.topology: Optional[Topology] = None

    def due(self, frame: int, time: float) -> bool:
        if self.cfg.latch_time is not None:
            return time >= self.cfg.latch_time - 1e-9
        return frame >= self.cfg.latch_frame

    def __call__(self, sim) -> Optional[Topology]:
        if self.topology is not None or not self.due(sim.frame, sim.time):
            return None
        self.topology = Topology.from_plane(sim.particles.x, self.cfg.point, self.cfg.normal, self.cfg.band_width * sim.grid.dx,
                                   latch_time=sim.time, latch_frame=sim.frame, pair_radius=self.cfg.pair_radius)
        return self.topology
