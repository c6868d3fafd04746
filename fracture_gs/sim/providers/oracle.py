"""Oracle provider: analytic planes from the config, each latched at its frame or time.

One plane (`topology.point`, `normal`, `latch_frame` / `latch_time`) is the paper's controlled
experiment. A list of timed planes (`[[topology.planes]]`) cuts again and again: each plane splits
every fragment it crosses (the new piece on its positive side), then connected components split.
"""

from __future__ import annotations

from typing import Optional

from ...config import OraclePlane, TopologyConfig
from ..topology import FractureEvent, Topology
from .cuts import RELEASE_EVENTS, finish_event, plane_cut


class OracleProvider:
    """Latches analytic planes from the config at configured frames or times."""

    def __init__(self, cfg: TopologyConfig):
        self.cfg = cfg
        self.planes = list(cfg.planes) or [OraclePlane(cfg.point, cfg.normal, cfg.latch_frame, cfg.latch_time)]
        self.next = 0
        self.topology: Optional[Topology] = None

    @staticmethod
    def plane_due(plane: OraclePlane, frame: int, time: float) -> bool:
        if plane.latch_time is not None:
            return time >= plane.latch_time - 1e-9
        return frame >= plane.latch_frame

    def due(self, frame: int, time: float) -> bool:
        """The next plane is due at this frame end."""
        return self.next < len(self.planes) and self.plane_due(self.planes[self.next], frame, time)

    def __call__(self, sim) -> Optional[Topology]:
        if not self.due(sim.frame, sim.time):
            return None
        cfg, x, width = self.cfg, sim.particles.x, self.cfg.band_width * sim.grid.dx
        t = self.topology
        while self.due(sim.frame, sim.time):
            plane = self.planes[self.next]
            self.next += 1
            if t is None:
                t = Topology.from_plane(
                    x,
                    plane.point,
                    plane.normal,
                    width,
                    latch_time=sim.time,
                    latch_frame=sim.frame,
                    pair_radius=cfg.pair_radius,
                )
                t.release_events = RELEASE_EVENTS[cfg.release]
                if cfg.split_components:
                    first, t = t.events[0], Topology(**{**t.__dict__, "events": []})
                    t = finish_event(sim, cfg, t, t.fragment, t.band, first)
                continue
            fragment, band, parents, children = plane_cut(
                x, t.fragment, t.band, plane.point, plane.normal, width, sim.cfg.max_fragments, tag=len(t.events) + 1
            )
            event = FractureEvent(
                "plane", sim.time, sim.frame, tuple(parents), tuple(children), tuple(plane.point), tuple(plane.normal)
            )
            t = finish_event(sim, cfg, t, fragment, band, event)
        self.topology = t
        return t
