"""Input/output: splat files (3DGS PLY, compressed PLY, .splat, .spz), TOML configs, videos. Imports neither
`sim` nor `render`.

The names below are imported on first use (PEP 562): a config (`io.config`) and a file's format
(`io.detect`) need neither torch nor numpy, so `fracture-gs validate` and the CLI's parser never load them.
"""

TYPE_CHECKING = False
if TYPE_CHECKING:  # for type checkers and IDEs; at run time __getattr__ imports them
    from .config import ConfigError, dump_config, load_config
    from .formats import detect_format, read_gaussians, write_gaussians
    from .gaussian_set import GaussianSet
    from .ply import PlyError, load_ply, save_ply

_WHERE = {
    "ConfigError": "config",
    "dump_config": "config",
    "load_config": "config",
    "detect_format": "detect",
    "read_gaussians": "formats",
    "write_gaussians": "formats",
    "GaussianSet": "gaussian_set",
    "PlyError": "ply",
    "load_ply": "ply",
    "save_ply": "ply",
}

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


def __getattr__(name: str) -> object:
    """`io.load_config`, `io.GaussianSet`, ...: the submodule that holds it, imported when first asked for."""
    import importlib

    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
