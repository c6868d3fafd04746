"""Simulate as many particles as the grid needs, draw every Gaussian: `sample`.

A capture can hold far more Gaussians than its grid needs particles (a 1M-Gaussian scan on a grid of
Δx = 1 cm needs a few tens of thousands; PhysDreamer simulates 13k points for a 1M-Gaussian scene). Each
grid cell takes about 8 particles (spacing Δx/2), so:

1. the surface Gaussians are binned into voxels of the particle spacing; in each voxel the most opaque one
   becomes a particle (a point the capture really has, not a voxel centre);
2. the interior fill particles (already at that spacing) are all particles;
3. every Gaussian is carried by its nearest particle at rest (`io.gaussian_set.Carrier`): it moves with that
   particle's position and deformation gradient, so fine Gaussians keep their detail and the cost follows the
   resolution, not the Gaussian count. Nearest means a Gaussian rides the piece it lies in when a crack passes
   between particles; interior fill particles carry themselves.

Particle volumes then come from the particles per cell as for any scene (`Particles.from_gaussians`), so the
mass of the object is ρ times its occupied cells however many Gaussians it had.
"""

from __future__ import annotations

import numpy as np
import torch

from ..io.gaussian_set import Carrier, GaussianSet


def sample(gs: GaussianSet, spacing: float) -> tuple[GaussianSet, str]:
    """`gs` (surface Gaussians and interior fill, simulation frame) with a carrier whose particles are one
    surface Gaussian per voxel of `spacing` [m] and every interior particle; and a note line. A set that is
    already no denser than that is returned as it is (every Gaussian simulated)."""
    surface = torch.nonzero(~gs.interior).flatten()
    interior = torch.nonzero(gs.interior).flatten()
    x = gs.means.detach().to(torch.float64).cpu()
    cell = torch.floor(x[surface] / spacing).to(torch.int64)
    cell -= cell.min(0).values
    span = cell.max(0).values + 1
    key = ((cell[:, 0] * span[1] + cell[:, 1]) * span[2] + cell[:, 2]).numpy()  # [S] voxel id
    # the most opaque Gaussian of each voxel: sort by voxel, then by opacity (descending), take the first
    order = np.lexsort((-gs.opacities.detach().cpu().numpy()[surface.numpy()], key))
    first = np.ones(len(order), dtype=bool)
    first[1:] = key[order][1:] != key[order][:-1]
    picked = surface[torch.from_numpy(order[first])]
    if len(picked) + len(interior) >= 0.8 * len(gs):
        return gs, f"particles: all {len(gs)} Gaussians simulated (no denser than {1e3 * spacing:.3g} mm spacing)"
    chosen = torch.cat([picked.sort().values, interior])
    particles = gs.subset(chosen.to(gs.means.device))
    from scipy.spatial import cKDTree

    tree = cKDTree(x[chosen].numpy())
    _, near = tree.query(x.numpy(), k=1)
    index = torch.from_numpy(near).to(torch.int64)
    index[interior] = torch.arange(len(picked), len(chosen))  # interior particles carry themselves
    offset = (x - x[chosen][index]).to(torch.float32)
    dev = gs.means.device
    carried = gs.replace(carrier=Carrier(particles, index.to(dev), offset.to(dev)))
    note = (
        f"particles: {len(chosen)} simulated ({len(picked)} of {len(surface)} surface Gaussians, one per "
        f"{1e3 * spacing:.3g} mm voxel, and {len(interior)} interior), carrying all {len(surface)} Gaussians"
    )
    return carried, note
