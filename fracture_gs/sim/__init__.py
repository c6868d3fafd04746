"""MLS-MPM simulation with FractureFields transfer (paper sections 3–4)."""
import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner or per-module load lines
_wp.config.enable_backward = False  # forward-only kernels compile in half the time
_wp.init()

from ..config import CuboidBoundary, MaterialConfig, ParticleRegion, PlaneBoundary, SimConfig, TopologyConfig
from .grid import Grid, fit_grid
from .particles import Particles, SimulationError
from .simulator import MULTIFIELD_VARIANTS, RELEASE_VARIANTS, SimulationDiverged, Simulator
from .topology import OracleProvider, Topology, make_provider

__all__ = [
    "CuboidBoundary", "Grid", "MaterialConfig", "MULTIFIELD_VARIANTS", "OracleProvider", "ParticleRegion", "Particles",
    "PlaneBoundary", "RELEASE_VARIANTS", "SimConfig", "SimulationDiverged", "SimulationError", "Simulator", "Topology",
    "TopologyConfig", "fit_grid", "make_provider",
]
