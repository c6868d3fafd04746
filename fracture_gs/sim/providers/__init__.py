"""Fracture event providers: who decides when and where an object breaks.

A provider is a callable `provider(sim) -> Topology | None`, asked once per frame after the
frame's substeps. The simulator latches the topology it returns (`Simulator.latch`); latching is
impulse-free, and a provider may return a newer topology later (repeated fracture). Providers:
`oracle` (timed analytic planes), `stress` (stress-guided detection, optionally repeated),
`voronoi` (a shatter into cells), `replay` (a saved history, so every variant of a run shares one).
"""

from __future__ import annotations

from typing import Optional, Protocol

from ...config import TopologyConfig
from ...errors import SimulationError
from ..topology import Topology
from .oracle import OracleProvider
from .replay import ReplayProvider
from .stress import StressProvider
from .voronoi import VoronoiProvider


class Provider(Protocol):
    """What the simulator calls once per frame."""

    def __call__(self, sim) -> Optional[Topology]: ...


def make_provider(cfg: TopologyConfig) -> Optional[Provider]:
    """The provider named by the config (None for `none`)."""
    if cfg.provider == "none":
        return None
    if cfg.provider == "oracle":
        return OracleProvider(cfg)
    if cfg.provider == "stress":
        return StressProvider(cfg)
    if cfg.provider == "voronoi":
        return VoronoiProvider(cfg)
    raise SimulationError(f"topology.provider '{cfg.provider}' is unknown; use none, oracle, stress or voronoi")


__all__ = ["OracleProvider", "Provider", "ReplayProvider", "StressProvider", "VoronoiProvider", "make_provider"]
