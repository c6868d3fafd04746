"""The ground a captured object stands on: found, kept static, and used as the floor (`find_ground`).

A capture of a statue or a plant outdoors holds the pavement or the table around it, often more Gaussians
than the object. Simulated, that sheet smears; and connected to the object it pulls the whole scene into the
region of interest. The ground is a flat layer at the bottom that spans the scene:

1. heights h = x·up of every Gaussian, binned in 1 % of their robust range (0.5–99.5 %);
2. the fullest bin in the lowest 30 % of the range is the candidate level;
3. it is the ground if it is a spike, at least `MIN_PEAK` times the mean of those bins (a flat layer, not the
   wide bottom of an object: the guitar's body reads 1.5, the seal's pavement 12), the Gaussians within two
   bins of it are at least `MIN_SHARE` of all, spread at least `MIN_SPREAD` as wide across the up axis as the
   whole capture, and leave at least `MIN_ABOVE` above it (an object, not a flat scan).

Gaussians up to two bins above the level are ground; they stay as a static background, drawn every frame.
"""

from __future__ import annotations

from typing import Optional

import torch

MIN_PEAK = 4.0
"""Least ratio of the ground bin's count to the mean count of the lowest 30 % of the height range."""
MIN_SHARE = 0.08
"""Least share of the Gaussians in the ground layer."""
MIN_SPREAD = 0.8
"""Least horizontal extent of the ground layer, as a fraction of the whole capture's."""
MIN_ABOVE = 0.2
"""Least share of the Gaussians above the ground (there is an object on it)."""


def find_ground(x: torch.Tensor, up: torch.Tensor) -> Optional[float]:  # x [N, 3], up [3]
    """The height along `up` (scene units) of the ground's top surface, or None when there is no ground."""
    x, up = x.to(torch.float64), up.to(torch.float64) / up.norm()
    h = x @ up  # [N]
    sample = h[torch.randperm(len(h))[:200_000]] if len(h) > 200_000 else h
    lo, hi = (float(v) for v in torch.quantile(sample, torch.tensor([0.005, 0.995], dtype=torch.float64)))
    if not hi > lo:
        return None
    width = (hi - lo) / 100.0
    low = h[(h >= lo) & (h < lo + 30 * width)]
    if len(low) == 0:
        return None
    counts = torch.histc(low, bins=30, min=lo, max=lo + 30 * width)
    if float(counts.max()) < MIN_PEAK * float(counts.mean()):
        return None
    level = lo + (int(counts.argmax()) + 0.5) * width
    layer = (h - level).abs() <= 2 * width
    top = level + 2 * width
    if float(layer.float().mean()) < MIN_SHARE or float((h > top).float().mean()) < MIN_ABOVE:
        return None
    flat = x - h[:, None] * up  # positions projected on the plane across `up`

    def spread(p: torch.Tensor) -> float:
        q = torch.quantile(p[torch.randperm(len(p))[:100_000]], torch.tensor([0.02, 0.98], dtype=torch.float64), 0)
        return float((q[1] - q[0]).norm())

    return top if spread(flat[layer]) >= MIN_SPREAD * spread(flat) else None
