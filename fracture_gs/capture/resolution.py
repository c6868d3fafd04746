"""Grid resolution chosen from the object: Δx that resolves its thinnest parts, within a budget per device.

A part thinner than a grid cell cannot bend or break on its own: its particles share every node with the
parts around it, so a stem or a leaf moves with its neighbours and smears. The resolution is therefore read
off the object:

1. the object's solid (its shell and what the shell encloses) on voxels of `size / PROBE_CELLS`;
2. the local thickness along its medial surface: twice the distance to the outside at the voxels where that
   distance peaks (a sheet k voxels thick peaks at (k + 1)/2, so thickness = 2·peak − 1 voxels);
3. the thin parts' thickness t: the `THIN_PERCENTILE`-th percentile of those thicknesses;
4. Δx = t / 2 (two cells across the thin parts), clamped to the cells across the object that
   `capture.quality` allows on the device, and coarsened until the particles the fill would make
   (8 per solid cell) fit the quality's particle budget.

The budgets are what a run can afford: on the CPU (Warp runs single-threaded) a 40-frame, three-variant run
of a captured object stays within a few minutes; on a GPU the grid goes much finer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..assets.fill import solid_voxels
from ..io.gaussian_set import GaussianSet

PROBE_CELLS = 128
"""Voxels across the object's longest side for the thickness probe."""
THIN_PERCENTILE = 10.0
"""Percentile of the medial thickness that counts as the object's thin parts [%]."""

BUDGETS = {
    "cpu": {"draft": (12, 24, 8_000), "default": (20, 44, 30_000), "fine": (32, 64, 80_000)},
    "cuda": {"draft": (32, 64, 150_000), "default": (48, 128, 600_000), "fine": (96, 256, 2_000_000)},
}
"""(fewest cells across, most cells across, most simulated particles) per device kind and quality."""


@dataclass
class Resolution:
    """The chosen grid resolution and what it resolves."""

    cells: int  # cells across the object's longest side
    dx: float  # cell size [m]
    thin: float  # thickness of the thin parts [m] (0: not measured)
    note: str
    budget: int = 0  # the quality's most simulated particles on the device


def probe(
    gs: GaussianSet, size: float, threshold: float, min_opacity: float, closing: int, seal_bottom: bool = False
) -> tuple[float, float]:
    """(thickness of the object's thin parts [m] (steps 1–3 of the module doc; 0 if it has no solid), its solid
    volume as a fraction of the size³ cube)."""
    h = size / PROBE_CELLS
    solid = solid_voxels(gs, h, threshold=threshold, min_opacity=min_opacity, closing=closing, seal_bottom=seal_bottom)
    if not bool(solid.any()):
        return 0.0, 0.0
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(solid.numpy())  # voxels to the nearest outside voxel
    ridge = (depth == ndimage.maximum_filter(depth, size=3)) & (depth > 0)
    t = torch.from_numpy(2.0 * depth[ridge] - 1.0).double()
    thin = max(1.0, float(torch.quantile(t, THIN_PERCENTILE / 100.0))) * h
    return thin, float(solid.sum()) / PROBE_CELLS**3


def choose(gs: GaussianSet, cap, device: str) -> Resolution:
    """Δx for the fitted object `gs` (simulation frame) under `cap.quality` on `device`; `cap.cells_across`,
    if set, is used as given."""
    size = cap.size
    kind = "cuda" if str(device).startswith("cuda") else "cpu"
    lo, hi, budget = BUDGETS[kind][cap.quality]
    thin, solid_fraction = probe(gs, size, cap.fill_threshold, cap.min_opacity, cap.fill_closing, cap.seal_bottom)
    if cap.cells_across is not None:
        cells = int(cap.cells_across)
        return Resolution(cells, size / cells, thin, _note(cells, size / cells, thin, "capture.cells_across"), budget)
    wanted = math.ceil(2.0 * size / thin) if thin > 0 else hi
    cells = min(max(wanted, lo), hi)
    particles = lambda c: 8.0 * solid_fraction * c**3  # noqa: E731  (8 per solid cell; c³ cells in the size cube)
    if solid_fraction > 0:  # the most cells whose particles fit the budget, never below the fewest
        fit = int((budget / (8.0 * solid_fraction)) ** (1 / 3))
        if particles(fit + 1) <= budget:  # the cube root's round-off lands one short of an exact fit
            fit += 1
        cells = max(lo, min(cells, fit))
    why = f"capture.quality = {cap.quality!r} on the {'GPU' if kind == 'cuda' else 'CPU'}"
    return Resolution(cells, size / cells, thin, _note(cells, size / cells, thin, why), budget)


def _note(cells: int, dx: float, thin: float, why: str) -> str:
    head = f"resolution: Δx = {1e3 * dx:.3g} mm, {cells} cells across ({why})"
    if thin <= 0:
        return head
    per = thin / dx
    line = f"{head}; its thin parts, ≈ {1e3 * thin:.3g} mm thick, get {per:.1f} cells"
    if per < 1.0:
        line += (
            " (under-resolved: they move with their neighbours and cannot break on their own; "
            'capture.quality = "fine" or a GPU resolves more)'
        )
    return line
