"""fracture-gs: fracture-aware MLS-MPM simulation and splatting of 3D Gaussian scenes.

import fracture_gs as fgs
gs = fgs.assets.build("bread")                    # or fgs.io.load_ply("scene.ply")
cfg = fgs.io.load_config("bread")
sim = fgs.sim.Simulator(cfg.sim, fgs.sim.Particles.from_gaussians(gs, cfg), device="cpu")
fgs.FractureSim(cfg)                              # torch.nn.Module facade

The subpackages are imported on first use (PEP 562), so `import fracture_gs` costs nothing: the console
entry point (`fracture_gs.cli:main`) imports torch and Warp inside its Ctrl-C handler, and an interrupt
while they load exits 130 like any other (DESIGN.md "Errors and validation").
"""

TYPE_CHECKING = False  # typing is not imported: a Ctrl-C during start-up should find as little to interrupt
__version__ = "0.1.0"
__all__ = ["FractureSim", "assets", "config", "io", "render", "sim", "__version__"]

_SUBMODULES = ("assets", "config", "io", "render", "sim")

if TYPE_CHECKING:  # for type checkers and IDEs; at run time __getattr__ imports them
    from . import assets, config, io, render, sim
    from .module import FractureSim


def __getattr__(name: str) -> object:
    """`fracture_gs.sim`, `fracture_gs.FractureSim`, ...: imported when first asked for."""
    import importlib

    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    if name == "FractureSim":
        return importlib.import_module(".module", __name__).FractureSim
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
