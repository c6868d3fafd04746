"""Label operations of fracture events: cut fragments by a plane, shatter into Voronoi cells, split
fragments into connected components. Each returns new labels and never touches x, v, C, F (an
event is impulse-free by construction: the simulator only copies the labels).

Connectivity is decided on the grid: a fragment's particles are binned into cells of size `h`
(Δx by default; particles sit ≈ Δx/2 apart) and cells sharing a face, edge or corner are connected
(scipy.ndimage.label, 26-connectivity). A plane cut through both arms of a U therefore leaves
three pieces. Components smaller than `min_particles` stay with their parent id, and no id is
created at or above `max_fragments` (the pieces that would need one stay with their parent).
"""

from __future__ import annotations

import numpy as np
import torch

_STRUCTURE = np.ones((3, 3, 3), dtype=bool)  # 26-connectivity


def plane_cut(
    x: torch.Tensor,
    fragment: torch.Tensor,
    band: torch.Tensor,
    point,
    normal,
    band_width: float,
    max_fragments: int,
    targets=None,
    tag: int = 1,
) -> tuple[torch.Tensor, torch.Tensor, list, list]:
    """Cut the `targets` fragments (all when None) by the plane through `point` with `normal`: in each
    fragment with particles on both sides, the positive side gets a new id. The band grows by the
    cut fragments' particles within `band_width` [m] of the plane, tagged with `tag` (the event's
    1-based index) where they had no band yet. Returns (fragment [N], band [N], parents, children)."""
    n = torch.as_tensor(normal, dtype=torch.float64, device=x.device)
    n = n / n.norm()
    d = (x.double() - torch.as_tensor(point, dtype=torch.float64, device=x.device)) @ n  # [N]
    fragment, band = fragment.clone(), band.clone()
    ids = torch.unique(fragment).tolist() if targets is None else list(targets)
    next_id = int(fragment.max()) + 1
    parents, children = [], []
    for f in ids:
        mine = fragment == f
        pos = mine & (d >= 0)
        if not bool(pos.any()) or not bool((mine & (d < 0)).any()):
            continue
        band = torch.where(mine & (d.abs() < band_width) & (band == 0), torch.full_like(band, tag), band)
        if next_id >= max_fragments:
            continue
        fragment[pos] = next_id
        parents.append(int(f))
        children.append(next_id)
        next_id += 1
    return fragment, band, parents, children


def voronoi_labels(x: torch.Tensor, seeds: torch.Tensor, band_width: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Cell of the nearest seed for every particle, and the band: particles closer than `band_width`
    [m] to the bisector with their second-nearest seed (distance (|x−s₂|² − |x−s₁|²) / 2|s₂−s₁|). A tie (a
    particle exactly as far from two seeds, as on a lattice) goes to the seed listed first, for s₁ and for s₂ alike,
    whatever the torch version or device (`topk` leaves the order of ties unspecified)."""
    xd, sd = x.double(), seeds.to(x.device, torch.float64)
    d2 = torch.cdist(xd, sd) ** 2  # [N, M]
    cell = torch.argmin(d2, dim=1)  # [N] the first of the nearest seeds
    if sd.shape[0] < 2:
        return cell.to(torch.int32), torch.zeros_like(cell, dtype=torch.int32)
    first = d2.gather(1, cell[:, None])[:, 0]  # [N] |x − s₁|²
    d2.scatter_(1, cell[:, None], float("inf"))  # s₁ out of the running: the first of the rest is s₂
    second = torch.argmin(d2, dim=1)  # [N]
    s1, s2 = sd[cell], sd[second]
    gap = (d2.gather(1, second[:, None])[:, 0] - first) / (2 * (s2 - s1).norm(dim=1).clamp_min(1e-30))
    return cell.to(torch.int32), (gap < band_width).to(torch.int32)


def split_components(
    x: torch.Tensor, fragment: torch.Tensor, h: float, max_fragments: int, min_particles: int = 8
) -> tuple[torch.Tensor, list, list]:
    """Give every disconnected piece of a fragment its own id (the largest piece keeps the old id).
    Returns (fragment [N], parents, children)."""
    xs = x.detach().double().cpu().numpy()
    frag = fragment.cpu().numpy().astype(np.int64)
    out = frag.copy()
    next_id = int(frag.max()) + 1
    from scipy import ndimage  # here, not at import: scipy.ndimage takes 0.15–0.4 s to load, an event runs once

    parents, children = [], []
    for f in np.unique(frag):
        idx = np.nonzero(frag == f)[0]
        if idx.size < 2 * min_particles:
            continue
        cell = np.floor(xs[idx] / h).astype(np.int64)
        cell -= cell.min(0)
        occ = np.zeros(cell.max(0) + 1, dtype=bool)
        occ[tuple(cell.T)] = True
        labels, count = ndimage.label(occ, structure=_STRUCTURE)
        if count < 2:
            continue
        lab = labels[tuple(cell.T)]  # [M] component of each particle, 1..count
        sizes = np.bincount(lab, minlength=count + 1)
        order = [c for c in np.argsort(-sizes) if c > 0 and sizes[c] >= min_particles]
        for c in order[1:]:  # the largest keeps the id
            if next_id >= max_fragments:
                break
            out[idx[lab == c]] = next_id
            parents.append(int(f))
            children.append(next_id)
            next_id += 1
    return torch.from_numpy(out.astype(np.int32)).to(fragment.device), parents, children


RELEASE_EVENTS = {"first": 1, "all": 1 << 30, "none": 0}  # TopologyConfig.release → Topology.release_events


def finish_event(sim, cfg, base, fragment: torch.Tensor, band: torch.Tensor, event):
    """The snapshot after `event`: labels split into connected components when the config asks for
    it (the new ids join the event's children), appended to `base` (None: the first event, whose
    snapshot `event` already is, as a Topology)."""
    from ..topology import Topology

    if cfg.split_components:
        fragment, parents, children = split_components(
            sim.particles.x, fragment, sim.grid.dx, sim.cfg.max_fragments, cfg.min_fragment_particles
        )
        event.parents = tuple(dict.fromkeys((*event.parents, *parents)))  # each cut fragment once, in order
        event.children = tuple(event.children) + tuple(children)
    if isinstance(base, Topology):
        out = base.refined(fragment, band, event)
        out.release_events = RELEASE_EVENTS[cfg.release]
        return out
    raise TypeError("finish_event needs the previous Topology")
