"""MLS-MPM simulation with FractureFields transfer (paper sections 3–4).

Importing this package has no side effects: Warp is initialised by the first `Simulator`
(`fracture_gs.runtime.ensure_warp`) and each kernel module sets its own compile options.
"""

from ..config import (
    ContactConfig,
    CuboidBoundary,
    MaterialConfig,
    ParticleRegion,
    PlaneBoundary,
    SimConfig,
    SphereBoundary,
    TopologyConfig,
)
from ..errors import SimulationDiverged
from .grid import layout
from .grid.domain import fit_grid
from .grid.fields import Grid
from .options import SimOptions
from .particles import Particles, SimulationError
from .providers import OracleProvider, ReplayProvider, StressProvider, make_provider
from .simulator import Simulator
from .topology import Topology

__all__ = [
    "layout",
    "ContactConfig",
    "CuboidBoundary",
    "Grid",
    "MaterialConfig",
    "OracleProvider",
    "ParticleRegion",
    "Particles",
    "PlaneBoundary",
    "ReplayProvider",
    "StressProvider",
    "SimConfig",
    "SimOptions",
    "SphereBoundary",
    "SimulationDiverged",
    "SimulationError",
    "Simulator",
    "Topology",
    "TopologyConfig",
    "fit_grid",
    "make_provider",
]
