"""Input/output: 3DGS PLY files, TOML configs, videos. Imports neither `sim` nor `render`."""

from .config import ConfigError, dump_config, load_config
from .gaussian_set import GaussianSet
from .ply import PlyError, load_ply, save_ply

__all__ = ["ConfigError", "GaussianSet", "PlyError", "dump_config", "load_config", "load_ply", "save_ply"]
