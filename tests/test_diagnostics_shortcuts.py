"""The per-frame diagnostics' shortcuts give the numbers of the plain computations they replace, bit for bit:

- `metrics.penetration` takes, per fragment-0 member, the smallest s = x·n over its near fragment-1 members
  (one pass over the pairs) instead of every pair's depth: max_q fl(s_p − s_q) = fl(s_p − min_q s_q).
- `Grid.field_sums_within` launches the dense sums over the box `Diagnostics._reach` says the particles' P2G
  stencils reach, instead of every node.
- `VoxelOverlap.packed` stops eroding on the CPU once no voxel is alive.
- The tracker's float64 particles (`tracker.Float64Particles`) give the metrics the numbers of the particles.
- `metrics.piece_gap` bounds its nearest-neighbour query by a sampled distance between the two pieces, and returns
  what the unbounded query of every particle returns.
"""

import math

import pytest
import torch
from test_many_fragments import voronoi_state

from fracture_gs.sim import simulator as S
from fracture_gs.sim.diagnostics import energy as E
from fracture_gs.sim.diagnostics import metrics as M
from fracture_gs.sim.diagnostics.overlap_kernels import VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import overlap_packed
from fracture_gs.sim.diagnostics.tracker import Float64Particles, Packed


def _penetration_pairwise(x, members, n, radius: float, chunk: int = 2048) -> torch.Tensor:
    """Every near pair's depth (x_p − x_q)·n, 0 elsewhere, the largest over all pairs and 0 (the plain formula),
    with `cdist` of the same chunks of members (its distances depend on its operands' sizes)."""
    a, b = members
    worst = torch.zeros((), dtype=torch.float64)
    if a.numel() == 0 or b.numel() == 0:
        return worst
    x = x.double()
    xb, sb = x[b], x[b] @ n
    for start in range(0, a.numel(), chunk):
        xa = x[a[start : start + chunk]]
        near = torch.cdist(xa, xb) < radius
        depth = (xa @ n)[:, None] - sb[None, :]
        worst = torch.maximum(worst, torch.where(near, depth, torch.zeros_like(depth)).max())
    return worst


def _same(a: torch.Tensor, b: torch.Tensor) -> bool:
    """Bitwise equal 0-d float64 tensors (signed zeros and NaN included)."""
    return a.view(torch.int64).item() == b.view(torch.int64).item()


def _lattice(seed: int, n: int, spacing: float):
    """Particles on a coarse lattice (many equal s = x·n and many distances equal to the radius), half of them
    fragment 0, all in the band."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randint(0, 6, (n, 3), generator=g).float() * spacing
    fragment = (torch.rand(n, generator=g) < 0.5).int()
    band = torch.ones(n, dtype=torch.int32)
    return x, fragment, band


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("chunk", [1, 5, 2048])
def test_penetration_equals_the_pairwise_formula(seed, chunk):
    """Lattice points (ties in s and distances exactly at the radius), a random normal or an axis (exact zero
    depths), radii that make no pair, some pairs or every pair near: the same bits as the pairwise formula."""
    x, fragment, band = _lattice(seed, 60, 0.25)
    members = M.band_members(fragment, band)
    g = torch.Generator().manual_seed(100 + seed)
    normals = [torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64), torch.randn(3, generator=g, dtype=torch.float64)]
    for n in normals:
        for radius in (0.1, 0.25, 0.5, 0.25 * math.sqrt(2.0), 10.0):
            got = M.penetration(x, members, n, radius, chunk=chunk)
            assert _same(got, _penetration_pairwise(x, members, n, radius, chunk)), (seed, chunk, radius)
            flipped = M.penetration(x, members, -n, radius, chunk=chunk)  # other signs of the depths
            assert _same(flipped, _penetration_pairwise(x, members, -n, radius, chunk))


def test_penetration_edge_cases():
    """No member on one side, members never near, only negative depths (0), a member with a non-finite position
    (never near: it counts for nothing), and a NaN normal (NaN wherever a pair is near, as the pairwise formula)."""
    x, fragment, band = _lattice(7, 40, 0.25)
    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    a, b = M.band_members(fragment, band)
    for members in ((a[:0], b), (a, b[:0]), (a[:0], b[:0])):
        assert _same(M.penetration(x, members, n, 0.5), _penetration_pairwise(x, members, n, 0.5))
    far = x.clone()
    far[b] += 100.0
    assert _same(M.penetration(far, (a, b), n, 0.5), torch.zeros((), dtype=torch.float64))
    behind = x.clone()
    behind[b, 2] += 1e-3  # every fragment-1 member a little ahead along n: every depth negative
    assert _same(M.penetration(behind, (a, b), n, 0.5), _penetration_pairwise(behind, (a, b), n, 0.5))
    for bad in (float("nan"), float("inf")):
        odd = x.clone()
        odd[a[0]] = bad
        odd[b[0], 0] = bad
        assert _same(M.penetration(odd, (a, b), n, 0.5, chunk=3), _penetration_pairwise(odd, (a, b), n, 0.5, 3))
    nan_normal = torch.full((3,), float("nan"), dtype=torch.float64)
    got = M.penetration(x, (a, b), nan_normal, 0.5)
    assert _same(got, _penetration_pairwise(x, (a, b), nan_normal, 0.5)) and math.isnan(got)


def _edge_particles(seed: int):
    """Particles spread over the whole grid and past its walls (stencils clamped into the grid), some exactly on
    the positions where ⌊(x − origin)/Δx − ½⌋ steps, cut into Voronoi pieces."""
    sim, topo = voronoi_state(seed, "cpu", cells=3, slots=4, n=600)
    P = sim.particles
    g = torch.Generator().manual_seed(seed)
    dx = sim.grid.dx
    x = -0.2 + 1.4 * torch.rand(len(P), 3, generator=g)
    steps = (torch.randint(0, 32, (len(P) // 4, 3), generator=g).float() + 0.5) * dx  # ξ − ½ an integer
    x[: len(steps)] = steps
    P.x.copy_(x)
    return sim, topo


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("spread", ["inside", "edges", "corner"])
def test_field_sums_within_the_reach_are_field_sums(seed, spread):
    """The shadow transfer's grid, its sums over every node and over `_reach`'s box: the same bits; no slot-0
    mass outside the box. Particles inside the grid, over all of it and past its walls, or crowded in one corner
    (the box at the grid's edge); a non-finite position gives the whole grid."""
    if spread == "inside":
        sim, topo = voronoi_state(seed, "cpu", cells=3, slots=4, n=600)
    else:
        sim, topo = _edge_particles(seed)
        if spread == "corner":
            sim.particles.x.mul_(0.05)
    sim.latch(topo)
    tracker = sim.diagnostics_tracker()
    tracker._transfer(Packed())
    shadow, K = tracker.shadow, sim.n_fragments
    box = tracker._reach()
    inside = torch.zeros(shadow.shape, dtype=torch.bool)
    inside[box[0] : box[3], box[1] : box[4], box[2] : box[5]] = True
    assert not bool((shadow.mp[..., 3] != 0)[~inside].any()), "every node with mass lies in the box"
    if spread == "inside":
        assert inside.sum() < inside.numel() // 2, "a box smaller than the grid"
    for whole, part in zip(shadow.field_sums(sim.eps_m, K), shadow.field_sums_within(sim.eps_m, K, box)):
        assert torch.equal(whole.view(torch.int64), part.view(torch.int64))
    sim.particles.x[0, 1] = float("nan")
    assert tracker._reach() is None


def _block(side: int, h: float, seed: int):
    """A solid block of `side`³ voxels with a particle at each centre (fragment 0; levels up to side/2), a second
    block beside it (fragment 1), and a few fragment-1 intruders inside the first."""
    g = torch.Generator().manual_seed(seed)
    ijk = torch.stack(torch.meshgrid(*[torch.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3).float()
    first = (ijk + 0.5) * h
    second = first + torch.tensor([side * h, 0.0, 0.0])
    corner = torch.zeros(1, 3)  # the voxels' origin: every centre half a voxel from a voxel face
    x = torch.cat([corner, first, second, first[torch.randint(0, len(first), (20,), generator=g)]])
    frag = torch.cat([torch.zeros(1 + len(first)), torch.ones(len(second) + 20)]).int()
    return x + 0.3, frag


@pytest.mark.parametrize("max_depth", [0, 1, 2, 3, 8])
@pytest.mark.parametrize("side", [4, 20])
def test_voxel_overlap_erosion_stops_where_it_changes_nothing(device, side, max_depth):
    """Blocks whose erosion ends before the last step (side 4) and that still have voxels alive after it (side
    20, levels capped at `max_depth`): the numbers of the torch twin, which always runs every step. (The twin
    tests of `test_overlap_kernels.py` end their erosion early with levels above 0.)"""
    h = 0.01
    x, frag = _block(side, h, side)
    got = VoxelOverlap(len(x), device).packed(x.to(device), frag.to(device), h, 2, max_depth).cpu()
    assert torch.equal(got, overlap_packed(x, frag, h, 2, max_depth))
    if side == 20:  # intruders as deep as the levels go
        assert got[1] >= min(max_depth, 5) * h * (1 - 1e-9) and (max_depth > 0) == (got[0] > 0)


def test_float64_particles_give_the_particles_numbers():
    """Momentum, energies and the interface metrics of the float64 particles: the numbers of the particles."""
    sim, topo = voronoi_state(3, "cpu", cells=2, slots=4, n=500)
    sim.latch(topo)
    P, D = sim.particles, Float64Particles(sim.particles)
    assert D.x.dtype == torch.float64 and D.fragment is P.fragment and D.x is D.x
    n = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    members = M.band_members(P.fragment, P.band)
    models = frozenset(int(m) for m in P.material.unique().tolist())
    pairs = [
        (M.momentum(P), M.momentum(D)),
        (E.energies(P, (0.0, 0.0, -9.8), (0.0, 0.0, 1.0), 0, models), E.energies(D, (0.0, 0.0, -9.8), (0, 0, 1.0), 0)),
        (M.penetration(P.x, members, n, 0.1), M.penetration(D.x, members, n, 0.1)),
        (M.identity_crossing(P.x, P.fragment, members, n), M.identity_crossing(D.x, P.fragment, members, n)),
        (M.stringing(P.F, members[0]), M.stringing(D.F, members[0])),
    ]
    for ours, theirs in pairs:
        assert torch.equal(ours.view(torch.int64), theirs.view(torch.int64))
    assert isinstance(P, S.Particles)


def _piece_gap_unbounded(x, fragment, dx):
    """The plain computation: every particle of the second-largest piece queried against the largest's tree."""
    from scipy.spatial import cKDTree

    ids, counts = torch.unique(fragment[fragment >= 0], return_counts=True)
    if len(ids) < 2:
        return 0.0
    a, b = ids[counts.argsort(descending=True)[:2]]
    d, _ = cKDTree(x[fragment == a].double().numpy()).query(x[fragment == b].double().numpy(), k=1)
    return float(d.min()) / dx


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("case", ["spread", "lattice ties", "apart", "tiny scale", "one near pair", "sampled pair"])
def test_piece_gap_bounded_query_is_the_unbounded_one(seed, case):
    """Bit for bit the unbounded query's gap, where the sampled particles miss the nearest pair, where pairs tie on
    a lattice (gap 0 included), where the pieces lie far apart, at scales whose squared distances are subnormal."""
    g = torch.Generator().manual_seed(seed)
    n = 500 + 700 * seed
    x = torch.rand(n, 3, generator=g, dtype=torch.float64)
    frag = torch.randint(-1, 3, (n,), generator=g)
    if case in ("one near pair", "sampled pair"):  # piece 0 the largest, piece 1 the second
        frag = torch.where(torch.rand(n, generator=g) < 0.6, 0, torch.where(torch.rand(n, generator=g) < 0.8, 1, -1))
    if case == "lattice ties":
        x = torch.round(x * 6) / 6
    elif case == "apart":
        x[frag == 1] += torch.tensor([3.0 + seed, 0.0, 0.0], dtype=torch.float64)
    elif case == "tiny scale":
        x = x * 1e-160
    elif case == "one near pair":  # two slabs 1 apart, one particle of each reaching across: not in the sample
        x[:, 0] = torch.where(frag == 1, x[:, 0] + 2.0, x[:, 0])
        ones = torch.nonzero(frag == 1).flatten()
        x[ones[1], 0] = 1.5 + 1e-3 * seed  # stride 64 samples ones[0], ones[64], ...
    elif case == "sampled pair":  # the same, the reaching particle one the sample holds: the bound is the gap itself
        x[:, 0] = torch.where(frag == 1, x[:, 0] + 2.0, x[:, 0])
        x[torch.nonzero(frag == 1).flatten()[64], 0] = 1.5 + 1e-3 * seed
    got = M.piece_gap(x, frag, 0.1)
    assert got == _piece_gap_unbounded(x, frag, 0.1)
    if case in ("one near pair", "sampled pair"):
        assert got < 6.0  # the reaching particle, not the slabs' gap of 10 Δx, sets it
