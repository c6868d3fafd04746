"""fracture-gs: fracture-aware MLS-MPM simulation and splatting of 3D Gaussian scenes."""
from . import config, io

__version__ = "0.1.0"
__all__ = ["config", "io", "__version__"]
