"""Does a captured object break like the real thing? The measures its targets are stated in.

* `edge_strength(img)`: mean |∇I| of the grey image over the object's pixels (those that differ from the
  background, the median colour of the image border). Blur and ghosting lower it, so a video whose last frame
  keeps ≥ 0.9 of frame 0's edge strength has kept its object crisp.
* `pieces(fragment, share)`: the fragments holding at least `share` of the particles, largest first (a crumb
  of 3 particles is not a piece).
"""

from __future__ import annotations

import numpy as np

OBJECT_DIFFERENCE = 0.12
"""Summed |RGB − background| (each in [0, 1]) above which a pixel belongs to the object."""


def edge_strength(img: np.ndarray) -> float:  # [H, W, 3] uint8 or float in [0, 1]
    """Mean gradient magnitude of the grey image over the object's pixels (0 for an empty image)."""
    p = img[..., :3].astype(np.float64)
    if img.dtype == np.uint8:
        p /= 255.0
    border = np.concatenate([p[0], p[-1], p[:, 0], p[:, -1]])
    obj = np.abs(p - np.median(border, 0)).sum(-1) > OBJECT_DIFFERENCE
    g = p.mean(-1)
    grad = np.hypot(np.abs(np.diff(g, axis=1))[:-1], np.abs(np.diff(g, axis=0))[:, :-1])
    m = obj[:-1, :-1]
    return float(grad[m].mean()) if m.any() else 0.0


def pieces(fragment: np.ndarray, share: float = 0.03) -> list[int]:  # [N] int fragment ids (−1: none)
    """Particle counts of the fragments holding at least `share` of all particles, largest first."""
    ids, counts = np.unique(fragment[fragment >= 0], return_counts=True)
    big = sorted((int(c) for c in counts if c >= share * len(fragment)), reverse=True)
    return big if len(ids) else []
