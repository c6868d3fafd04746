"""The per-frame metrics as device tensors (docs/DESIGN.md "Diagnostics"): each function returns 0-d
(or small) float64 tensors and never reads back to the host, so the tracker (`tracker.py`)
packs a whole frame's numbers into one tensor and reads it once.
"""

from __future__ import annotations

import math

import torch

from ...linalg import singular_values
from ...runtime import device_constant

SEPARATION = 0.1  # Δx: an interface whose opening exceeds this has separated (docs/DESIGN.md)
GAP_STRIDE = 64  # `piece_gap`: every this many particles of the second piece give the first bound on the gap


def per_fragment_sum(values: torch.Tensor, fragment: torch.Tensor, K: int) -> torch.Tensor:  # -> [K]
    """Σ values over the particles of each fragment k < K (ids outside [0, K) ignored). On a GPU the
    particles add into 256 rows of partial sums (particle index mod 256), summed after: a plain
    index_add_ of 10⁵ particles into a few bins serialises its atomics on the same addresses."""
    rows = 256 if values.is_cuda else 1
    ok = (fragment >= 0) & (fragment < K)
    idx = (torch.arange(values.shape[0], device=values.device) % rows) * K + fragment.clamp(0, K - 1)
    out = torch.zeros(rows * K, dtype=values.dtype, device=values.device)
    return out.index_add_(0, idx, torch.where(ok, values, torch.zeros_like(values))).view(rows, K).sum(0)


def reapproach_ratio(open_max: float, opening: float) -> float:
    """Drop of the opening below its running maximum, over that maximum, with the maximum floored at
    the separation threshold: an interface that never opened past noise level would otherwise
    divide by noise (a 0.01 Δx drop below a 0.001 Δx maximum reads 10)."""
    return max(0.0, open_max - opening) / max(open_max, SEPARATION)


def interface_pairs(x, fragment, band, radius: float, chunk: int = 2048):
    """Each band particle of fragment 0 paired with its nearest band particle of fragment 1 within
    `radius` [m]; returns index tensors (p, q). Once per latch (it reads sizes back)."""
    a = torch.nonzero((fragment == 0) & (band != 0)).flatten()
    b = torch.nonzero((fragment == 1) & (band != 0)).flatten()
    if a.numel() == 0 or b.numel() == 0:
        return a[:0], b[:0]
    xb = x[b].double()
    ps, qs = [], []
    for start in range(0, a.numel(), chunk):
        ia = a[start : start + chunk]
        d, j = torch.cdist(x[ia].double(), xb).min(dim=1)
        keep = d < radius
        ps.append(ia[keep])
        qs.append(b[j[keep]])
    return torch.cat(ps), torch.cat(qs)


def raw_opening(x, pairs, n) -> torch.Tensor:  # -> []
    """Mean over interface pairs of (x_q − x_p)·n [m] (0 without pairs)."""
    p, q = pairs
    if p.numel() == 0:
        return torch.zeros((), dtype=torch.float64, device=x.device)
    x = x.double()
    return ((x[q] - x[p]) @ n).mean()


def band_members(fragment, band):
    """(fragment 0's band particles, fragment 1's) as index tensors: fixed after a latch, so the
    tracker computes them once per latch (they read sizes back)."""
    a = torch.nonzero((fragment == 0) & (band != 0)).flatten()
    b = torch.nonzero((fragment == 1) & (band != 0)).flatten()
    return a, b


def penetration(x, members, n, radius: float, chunk: int = 2048) -> torch.Tensor:  # -> [] [m]
    """Largest overlap along n near the interface: for every band particle p of fragment 0, how far
    its current neighbours q of fragment 1 (band, within `radius`) lie behind it, max(0, (x_p − x_q)·n).
    Current neighbours follow tangential sliding. Per p the deepest is fl(s_p − min over its neighbours of
    s_q), s = x·n: rounding is monotone, so it equals the largest fl(s_p − s_q), and only the minimum needs a
    pass over the pairs (`cdist`'s distances, written over with s_q, or +∞ where not near)."""
    a, b = members
    worst = torch.zeros((), dtype=torch.float64, device=x.device)
    if a.numel() == 0 or b.numel() == 0:
        return worst
    x = x.double()
    xb, sb = x[b], x[b] @ n
    inf = torch.full((), torch.inf, dtype=torch.float64, device=x.device)
    for start in range(0, a.numel(), chunk):
        xa = x[a[start : start + chunk]]
        d = torch.cdist(xa, xb)  # [A, B]
        nearest = torch.where(d < radius, sb, inf, out=d).amin(1)  # [A] min s_q over the near q (+∞: none)
        depth = torch.where(nearest == inf, 0.0, (xa @ n) - nearest)  # [A] (a p with no near q: 0, as before)
        worst = torch.maximum(worst, depth.max())
    return worst


def identity_crossing(x, fragment, members, n) -> torch.Tensor:  # -> [] count
    """Particles on the other fragment's side of the separating plane: normal n_Π, placed midway
    between the facing band fronts (max s over fragment 0's band, min s over fragment 1's) as they
    move. While the fronts have not passed each other no particle crosses; a fixed plane would count
    particles of a fragment that merely moved past where the interface used to be."""
    a, b = members
    if a.numel() == 0 or b.numel() == 0:
        return torch.zeros((), dtype=torch.float64, device=x.device)
    s = x.double() @ n
    mid = 0.5 * (s[a].max() + s[b].min())
    return (((fragment == 0) & (s > mid)).sum() + ((fragment == 1) & (s < mid)).sum()).double()


def stringing(F, band_index) -> torch.Tensor:  # -> []
    """Mean over band particles of ln(s_max / s_min) of F's singular values."""
    if band_index.numel() == 0:
        return torch.zeros((), dtype=torch.float64, device=F.device)
    s = singular_values(F[band_index].double())  # Warp kernel, float64
    return torch.log(s[:, 0] / s[:, 2].clamp_min(1e-12)).mean()


def momentum(P) -> torch.Tensor:  # -> [3]
    return (P.mass.double()[:, None] * P.v.double()).sum(0)


def kinetic_energy(P) -> torch.Tensor:  # -> []
    return 0.5 * (P.mass.double() * (P.v.double() ** 2).sum(1)).sum()


def plane_constants(plane, device) -> tuple[torch.Tensor, torch.Tensor]:
    """(unit normal [3], point [3]) of a plane collider as float64 tensors on `device`, from constants made
    once (`runtime.device_constant`)."""
    n = device_constant([float(a) for a in plane.normal], torch.float64, device)
    return n / n.norm(), device_constant([float(a) for a in plane.point], torch.float64, device)


def plane_state(x, v, fragment, plane, dx: float, K: int) -> dict:
    """Fragment–plane numbers of this frame for one plane collider: per fragment whether it is within
    Δx of the plane [K], deepest penetration behind it [m], max tangential speed within Δx, max
    normal speed within 2Δx."""
    n, point = plane_constants(plane, x.device)
    d = (x.double() - point) @ n
    vd = v.double()
    vn = vd @ n
    vt = (vd - vn[:, None] * n).norm(dim=1)
    near = d < dx
    touch = per_fragment_sum(near.double(), fragment.long(), K)
    zero = torch.zeros((), dtype=torch.float64, device=x.device)
    return {
        "touch": touch > 0,
        "penetration": (-d).clamp_min(0).max(),
        "vt_near": torch.where(near, vt, zero).max(),
        "vn_close": torch.where(d < 2 * dx, vn.abs(), zero).max(),
    }


def piece_gap(x: torch.Tensor, fragment: torch.Tensor, dx: float) -> float:  # x [N, 3], fragment [N]
    """Gap between the two largest fragments [Δx]: the shortest distance from a particle of one to a particle of
    the other (0 for fewer than two fragments). Where many pieces form, the first event's interface (`opening`)
    can be pushed shut while the pieces fly apart; this says whether the object came apart."""
    ids, counts = torch.unique(fragment[fragment >= 0], return_counts=True)
    if len(ids) < 2:
        return 0.0
    a, b = ids[counts.argsort(descending=True)[:2]]
    from scipy.spatial import cKDTree

    pa, pb = x[fragment == a].detach().cpu().double().numpy(), x[fragment == b].detach().cpu().double().numpy()
    tree = cKDTree(pa)
    # every GAP_STRIDE-th particle of b first: its nearest distance u is a distance between the pieces, so the gap is at
    # most u and the whole query may skip what lies farther (the same nearest pairs and distances; 2.7x less CPU)
    u = float(tree.query(pb[::GAP_STRIDE], k=1)[0].min())
    bound = u * (1.0 + 2.0**-20)  # the query compares squared distances: the bound's square must stay above u²
    if not (math.isfinite(bound) and bound * bound > u * u):  # u = 0, or a square that underflows
        bound = math.inf
    d, _ = tree.query(pb, k=1, distance_upper_bound=bound)
    return float(d.min()) / dx


def collider_packed(x: torch.Tensor, planes, tolerance: float) -> torch.Tensor:
    """`collider_crossing` as a device tensor [2] float64 (count, deepest distance [m]), no host read."""
    out = torch.zeros(2, dtype=torch.float64, device=x.device)
    xd = x.double()
    for b in planes:
        n, point = plane_constants(b, x.device)
        d = (xd - point) @ n
        below = d < -tolerance
        out[0] += below.sum()
        out[1] = torch.maximum(out[1], torch.where(below, -d, torch.zeros_like(d)).max())
    return out


def collider_crossing(x: torch.Tensor, planes, tolerance: float) -> tuple[int, float]:
    """(particles behind a plane collider by more than `tolerance` [m], deepest such distance [m])."""
    count, depth = 0, 0.0
    xd = x.double()
    for b in planes:
        n, point = plane_constants(b, x.device)
        d = (xd - point) @ n
        below = d < -tolerance
        count += int(below.sum())
        if bool(below.any()):
            depth = max(depth, float(-d[below].min()))
    return count, depth
