"""fracture-gs: fracture-aware MLS-MPM simulation and splatting of 3D Gaussian scenes.

import fracture_gs as fgs
gs = fgs.assets.build("bread")                    # or fgs.io.load_ply("scene.ply")
cfg = fgs.io.load_config("bread")
sim = fgs.sim.Simulator(cfg.sim, fgs.sim.Particles.from_gaussians(gs, cfg), device="cpu")
fgs.FractureSim(cfg)                              # torch.nn.Module facade
"""

from . import assets, config, io, render, sim
from .module import FractureSim

__version__ = "0.1.0"
__all__ = ["FractureSim", "assets", "config", "io", "render", "sim", "__version__"]
