"""Input/output: 3DGS PLY files, TOML configs, videos. Imports neither `sim` nor `render`."""
from .gaussian_set import GaussianSet

__all__ = ["GaussianSet"]
