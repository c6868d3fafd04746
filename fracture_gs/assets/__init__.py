"""Procedural built-in scenes and interior fill.

`build(name, size="small", seed=0, n=None)` returns a volumetric `GaussianSet` (drawn surface
Gaussians + interior fill particles, int32 material labels) for one of `names()`; the geometries
are documented in `fracture_gs.assets.scenes`. `fill_interior(gs)` adds interior particles to a
surface-only reconstruction.
"""

from __future__ import annotations

import numbers

from ..errors import SceneError
from ..io.gaussian_set import GaussianSet
from .builder import SceneSpec, build_scene
from .fill import fill_interior
from .scenes import SCENES

SIZES = {"small": 20_000}  # `paper` uses each scene's own count (ficus 171,553, bread 182,959)


MAX_BUILT = 100_000_000
"""The most particles a built-in scene is built with (the config's particle cap, io.config.validate.MAX_PARTICLES)."""


def names() -> list[str]:
    """Names of the built-in scenes."""
    return list(SCENES)


def build(
    name: str, size: str = "small", seed: int = 0, n: int | None = None, sh_degree: int = 1, device="cpu"
) -> GaussianSet:
    """Build scene `name` with `size` (`small` ≈ 20k, `paper` = the paper's count) or exactly `n`
    particles; deterministic for a given seed."""
    if name not in SCENES:
        raise SceneError(f"unknown built-in scene '{name}'; valid names are: {', '.join(SCENES)}.")
    spec = SCENES[name]
    if size not in ("small", "paper"):
        raise SceneError(f"unknown size {size!r:.40} for scene '{name}'; use 'small' or 'paper'.")
    if n is None:
        n = spec.paper_n if size == "paper" else SIZES[size]
    for arg, value in (("n", n), ("seed", seed), ("sh_degree", sh_degree)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise SceneError(f"scene '{name}': {arg} = {value!r:.40} is not a whole number; pass an int, e.g. {arg}=1.")
    if int(n) < 1 or not 0 <= int(sh_degree) <= 3:
        raise SceneError(
            f"scene '{name}': n must be ≥ 1 and sh_degree in 0..3 (got n={n}, sh_degree={sh_degree}); pass e.g. "
            "n=1000, sh_degree=1."
        )
    if not -(2**63) <= int(seed) < 2**64:  # torch's generator takes a 64-bit seed (2**70 was an OverflowError)
        raise SceneError(f"scene '{name}': seed = {int(seed)} does not fit in 64 bits; pass e.g. seed=0.")
    if int(n) > MAX_BUILT:
        raise SceneError(
            f"scene '{name}': n = {int(n):,} is more than {MAX_BUILT:,} particles (about 20 GB of state); pass a "
            "smaller n."
        )
    from ..io.ply import as_device

    device = as_device("assets.build", device)
    return build_scene(spec, int(n), seed=seed, sh_degree=int(sh_degree), device=device)


__all__ = ["build", "names", "fill_interior", "SceneSpec", "SCENES"]
