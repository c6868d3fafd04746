"""Voronoi provider: the standard VFX shatter, pre-fracturing the object into `cells` pieces.

Cell sites are particles drawn with a fixed seed: uniformly over the object, or with probability
∝ exp(−|x − c|² / 2r²) around `impact_point` c (more, smaller pieces near the impact). Every
particle takes the cell of its nearest site; the band is the particles within `band_width`·Δx of a
cell face; connected components split non-convex cells. It latches at `latch_frame` /
`latch_time`, or at the first frame end where a particle comes within Δx of a plane collider
(`latch_on_contact`). One event, impulse-free like every latch.
"""

from __future__ import annotations

from typing import Optional

import torch

from ...config import PlaneBoundary, TopologyConfig
from ..topology import FractureEvent, Topology
from .cuts import RELEASE_EVENTS, finish_event, voronoi_labels


def voronoi_sites(
    x: torch.Tensor, cells: int, seed: int, impact_point=None, impact_radius: float = 0.1
) -> torch.Tensor:
    """`cells` distinct particles of x [N,3] as sites [cells,3] (float64, on x's device)."""
    g = torch.Generator().manual_seed(int(seed))
    xd = x.detach().double().cpu()
    if impact_point is None:
        w = torch.ones(len(xd), dtype=torch.float64)
    else:
        r2 = ((xd - torch.tensor(impact_point, dtype=torch.float64)) ** 2).sum(1)
        w = torch.exp(-(r2 - r2.min()) / (2 * impact_radius**2)) + 1e-12
    idx = torch.multinomial(w, min(int(cells), len(xd)), replacement=False, generator=g)
    return xd[idx].to(x.device)


class VoronoiProvider:
    """Shatters the object into Voronoi cells once, at a time, a frame or the first contact."""

    def __init__(self, cfg: TopologyConfig):
        self.cfg = cfg
        self.topology: Optional[Topology] = None
        self.sites: Optional[torch.Tensor] = None

    def due(self, sim) -> bool:
        cfg = self.cfg
        if cfg.latch_on_contact:
            planes = [b for b in sim.cfg.boundaries if isinstance(b, PlaneBoundary)]
            x = sim.particles.x.double()
            for b in planes:
                n = torch.tensor(b.normal, dtype=torch.float64, device=x.device)
                d = (x - torch.tensor(b.point, dtype=torch.float64, device=x.device)) @ (n / n.norm())
                if float(d.min()) < sim.grid.dx:
                    return True
            return False
        if cfg.latch_time is not None:
            return sim.time >= cfg.latch_time - 1e-9
        return sim.frame >= cfg.latch_frame

    def __call__(self, sim) -> Optional[Topology]:
        if self.topology is not None or not self.due(sim):
            return None
        cfg, x = self.cfg, sim.particles.x
        self.sites = voronoi_sites(
            x, min(cfg.cells, sim.cfg.max_fragments), cfg.seed, cfg.impact_point, cfg.impact_radius
        )
        fragment, band = voronoi_labels(x, self.sites, cfg.band_width * sim.grid.dx)
        k = int(fragment.max()) + 1
        first = FractureEvent("voronoi", sim.time, sim.frame, (-1,), tuple(range(k)), seeds=self.sites.tolist())
        base = Topology(
            fragment=fragment,
            band=band,
            normal=(1.0, 0.0, 0.0),
            point=tuple(self.sites[0].tolist()),
            latch_time=sim.time,
            latch_frame=sim.frame,
            pair_radius=cfg.pair_radius,
            release_events=RELEASE_EVENTS[cfg.release],
        )
        self.topology = (
            finish_event(sim, cfg, base, fragment, band, first)
            if cfg.split_components
            else base.refined(fragment, band, first)
        )
        return self.topology
