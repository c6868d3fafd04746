"""Input/output: 3DGS PLY files, TOML configs, videos. Imports neither `sim` nor `render`."""
from .gaussian_set import GaussianSet
from .ply import PlyError, load_ply, save_ply

__all__ = ["GaussianSet", "PlyError", "load_ply", "save_ply"]
