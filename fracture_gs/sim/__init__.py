"""MLS-MPM simulation with FractureFields transfer (paper sections 3–4)."""
import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner or per-module load lines
_wp.config.enable_backward = False  # forward-only kernels compile in half the time


def _init_warp() -> None:
    """Initialize Warp. On a machine without a CUDA driver, Warp's native init prints a driver
    warning to stderr that would break one-line CLI errors; it is silenced there (`fracture-gs
    info` reports the devices instead)."""
    import os
    import sys

    import torch

    if torch.cuda.is_available():
        _wp.init()
        return
    sys.stderr.flush()
    saved, devnull = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        _wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


_init_warp()

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
