"""Input/output: splat files (3DGS PLY, compressed PLY, .splat, .spz), TOML configs, videos. Imports neither
`sim` nor `render`."""

from .config import ConfigError, dump_config, load_config
from .formats import detect_format, read_gaussians, write_gaussians
from .gaussian_set import GaussianSet
from .ply import PlyError, load_ply, save_ply

__all__ = [
    "ConfigError",
    "GaussianSet",
    "PlyError",
    "detect_format",
    "dump_config",
    "load_config",
    "load_ply",
    "read_gaussians",
    "save_ply",
    "write_gaussians",
]
