"""The surface measure's shortcuts give bit for bit what the plain formulas give.

`_max_around` pools one axis at a time where `max_pool3d` pools the 3×3×3 block; `_mixed_around` marks the entries
whose 27 cells hold two ids, from an int32 grid; `_nearest` over every particle visits each pair of neighbour cells
once and reads the pair for both ends; `calibrate` sums only the pairs `_adds_something` keeps; `surface_depth`
bins for the near test only the particles by another fragment; the Warp walks step along a run of keys instead of
searching each (`penetration_kernels.lower_bound_next`); `surface_penetration` sums a frame up on a dense table of
pairs read once (`_summary_dense`) instead of sorted keys read eight times. Each against the straightforward
computation, on ties, repeats, empty sets, cell faces and non-finite values."""

import math

import pytest
import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.diagnostics import penetration as pen
from fracture_gs.sim.diagnostics import penetration_kernels as pk


def _bits(t: torch.Tensor) -> torch.Tensor:  # float64 values as their bit patterns (NaN compares equal to itself)
    return t.contiguous().view(torch.int64)


@pytest.mark.parametrize("seed", range(4))
def test_max_around_is_max_pool3d(seed):
    """Random values (ties included) in a grid with a −∞ layer around: the same maxima as a padded 3×3×3 pool."""
    g = torch.Generator().manual_seed(seed)
    d = torch.randint(1, 7, (3,), generator=g).tolist()
    inner = torch.randint(-3, 4, (2, *d), generator=g).float()
    inner[torch.rand(inner.shape, generator=g) < 0.3] = -math.inf
    grid = torch.full((2, d[0] + 2, d[1] + 2, d[2] + 2), -math.inf)
    grid[:, 1:-1, 1:-1, 1:-1] = inner
    want = torch.nn.functional.max_pool3d(inner[:, None], 3, stride=1, padding=1)[:, 0]
    assert torch.equal(pen._max_around(grid), want)


def _mixed_by_pairs(c: torch.Tensor, fmin: torch.Tensor, fmax: torch.Tensor) -> torch.Tensor:
    """The rule itself: over every entry whose cell is within one of this entry's on each axis, min ≠ max."""
    close = ((c[:, None, :] - c[None, :, :]).abs() <= 1).all(2)  # [n, n]
    lo = torch.where(close, fmin[None, :], torch.full_like(close, 1 << 40, dtype=torch.long)).amin(1)
    hi = torch.where(close, fmax[None, :], torch.full_like(close, -(1 << 40), dtype=torch.long)).amax(1)
    return lo != hi


@pytest.mark.parametrize("seed", range(6))
def test_mixed_around_follows_the_rule(seed):
    """Entries in a small box (many in one cell, cells on the box's faces, unlabelled −1 ids, the largest ids the
    grid takes and their negatives) are mixed exactly where their 27 cells hold two ids; one id everywhere: none."""
    g = torch.Generator().manual_seed(seed)
    n = 300
    c = torch.randint(3, 3 + [2, 5, 9, 14, 4, 7][seed], (n, 3), generator=g)
    ids = torch.tensor([-1, 0, 1, 2, (1 << 24) - 1, -(1 << 24) + 1])
    fmin = ids[torch.randint(0, 4 if seed % 2 else 6, (n,), generator=g)]
    fmax = torch.maximum(fmin, ids[torch.randint(0, 4, (n,), generator=g)]) if seed > 3 else fmin
    got = pen._mixed_around(c, fmin, fmax)
    assert got is not None and torch.equal(got, _mixed_by_pairs(c, fmin, fmax))
    one = torch.full((n,), 5)
    assert not pen._mixed_around(c, one, one).any()


def test_mixed_around_declines_what_it_cannot_hold(monkeypatch):
    """An id of 2²⁴ or more in size, or a box over DENSE_CELLS cells: None (the sorted-key path decides)."""
    c = torch.tensor([[3, 3, 3], [4, 3, 3]])
    assert pen._mixed_around(c, torch.tensor([0, 1 << 24]), torch.tensor([0, 1 << 24])) is None
    assert pen._mixed_around(c, torch.tensor([-(1 << 24), 0]), torch.tensor([0, 0])) is None
    monkeypatch.setattr(pen, "DENSE_CELLS", 5)
    assert pen._mixed_around(torch.tensor([[3, 3, 3], [9, 3, 3]]), torch.tensor([0, 1]), torch.tensor([0, 1])) is None


@pytest.mark.parametrize("seed", range(4))
def test_nearest_over_every_particle_is_the_per_query_walk(seed):
    """`_nearest(query=None)` and the walk from each particle give the same bits: points on cell faces, repeated
    points (distance 0), one-particle fragments (inf), fragments side by side."""
    g = torch.Generator().manual_seed(seed)
    size = 0.1
    x = torch.rand(400, 3, generator=g, dtype=torch.float64)
    x[:80] = torch.round(x[:80] / size) * size  # on the faces of the cells
    x[80:100] = x[100:120]  # repeats
    frag = torch.randint(0, 3, (400,), generator=g)
    frag[80:100] = frag[100:120]  # repeats of the same fragment
    frag[-3:] = torch.tensor([7, 8, 9])  # alone in their fragment
    every = pen._nearest(x, frag, None, size)
    each = pen._nearest(x, frag, torch.arange(400), size)
    assert torch.equal(_bits(every), _bits(each))
    assert torch.isinf(every[-3:]).all() and (every[80:100] == 0).all()


def _sums(rows: torch.Tensor, S: int, w: torch.Tensor, d: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Σ w, Σ w·d and Σ w·d dᵀ per row, each pair in its order."""
    z = torch.zeros
    return (
        z(S, dtype=torch.float64).index_add_(0, rows, w),
        z(S, 3, dtype=torch.float64).index_add_(0, rows, w[:, None] * d),
        z(S, 3, 3, dtype=torch.float64).index_add_(0, rows, w[:, None, None] * d[:, :, None] * d[:, None, :]),
    )


@pytest.mark.parametrize("finite_weights", [True, False])
def test_calibration_sums_over_the_kept_pairs_are_the_sums_over_all(finite_weights):
    """The kernel sums of `calibrate` (the large ball's, weighted where the piece matches, and the small ball's, of
    a radius per pair) over the pairs `_adds_something` keeps equal, bit for bit, the sums over every pair: pairs at
    u² = 1 exactly and one ulp below, weights 0, −0, inf and NaN, an offset so large its square overflows, a radius
    0 (0/0), rows with no pair kept."""
    g = torch.Generator().manual_seed(3)
    P, S, R = 4000, 40, 1.0
    d = (torch.rand(P, 3, generator=g, dtype=torch.float64) - 0.5) * 3.0
    d[:50] = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)  # u² = 1 exactly
    d[50:100] = torch.tensor([math.nextafter(1.0, 0.0), 0.0, 0.0], dtype=torch.float64)
    d[100] = torch.tensor([1e200, 0.0, 0.0], dtype=torch.float64)  # d² overflows
    rows = torch.randint(0, S - 5, (P,), generator=g)  # the last rows get no pair
    same = torch.rand(P, generator=g) < 0.7
    J = 0.5 + torch.rand(P, generator=g, dtype=torch.float64)
    J[200:210], J[210:220] = 0.0, -0.0
    if not finite_weights:
        J[220:230], J[230:240] = math.inf, math.nan
    radius = 0.3 + torch.rand(P, generator=g, dtype=torch.float64)
    radius[240:245] = 0.0
    d[240:242] = 0.0
    d2 = (d**2).sum(1)
    odd = None if bool(torch.isfinite(J).all()) else ~torch.isfinite(J)
    u2 = d2 / (R * R)
    keep = same & (u2 < 1.0)
    w = torch.where(keep, pen.kernel(u2, R), torch.zeros_like(u2)) * J
    a = torch.nonzero(pen._adds_something(keep, u2, odd)).flatten()
    wa = torch.where(keep[a], pen.kernel(u2[a], R), torch.zeros_like(u2[a])) * J[a]
    assert a.numel() < P
    for full, part in zip(_sums(rows, S, w, d)[:2], _sums(rows[a], S, wa, d[a])[:2]):
        assert torch.equal(_bits(full), _bits(part))
    v2 = d2 / (radius * radius)
    ws = pen.kernel(v2, radius) * J
    b = torch.nonzero(pen._adds_something(v2 < 1.0, v2, odd)).flatten()
    for full, part in zip(_sums(rows, S, ws, d), _sums(rows[b], S, pen.kernel(v2[b], radius[b]) * J[b], d[b])):
        assert torch.equal(_bits(full), _bits(part))


@pytest.mark.parametrize("seed", range(3))
def test_near_walk_over_the_particles_by_another_fragment_alone(seed):
    """The near test of `surface_depth` over cells holding only the particles marked by `near_foreign` finds what it
    finds over every particle: blocks of three pieces and unlabelled particles, some exactly `reach` apart."""
    g = torch.Generator().manual_seed(seed)
    reach = 0.05
    x = torch.rand(3000, 3, generator=g, dtype=torch.float64)
    frag = (x[:, 0] * 3).long().clamp_max(2)
    frag[torch.rand(3000, generator=g) < 0.05] = -1
    x[:20] = x[20:40] + torch.tensor([reach, 0.0, 0.0], dtype=torch.float64)  # pairs at exactly `reach`
    frag[:20] = (frag[20:40] + 1) % 3
    lo = torch.where((frag >= 0)[:, None], x, torch.full_like(x, math.inf)).min(0).values
    full = pen._Cells(x, frag, lo, reach)
    near = full.near_foreign()
    query = torch.nonzero(near & (frag >= 0)).flatten()
    some = pen._Cells(x, frag, lo, reach, among=torch.nonzero(near).flatten(), coord=full.coord)
    a = pk.near_another_piece_mask(x, frag, full, query, reach, pen._BITS)
    b = pk.near_another_piece_mask(x, frag, some, query, reach, pen._BITS)
    assert torch.equal(a, b) and 0 < int(a.sum()) < query.numel()


@wp.kernel
def _walk(
    keys: wp.array(dtype=wp.int64),
    asked: wp.array(dtype=wp.int64),
    stepped: wp.array(dtype=wp.int32),
    searched: wp.array(dtype=wp.int32),
):
    """Each asked key in turn, by `lower_bound_next` from the previous answer and by a plain binary search."""
    last_key = wp.int64(0)
    last = int(0)  # noqa: UP018 - a typed variable Warp may change in the loop
    for k in range(asked.shape[0]):
        i = pk.lower_bound_next(keys, asked[k], last_key, last, k)
        stepped[k] = i
        searched[k] = pk.lower_bound(keys, asked[k])
        last_key = asked[k]
        last = i


@pytest.mark.parametrize("seed", range(3))
def test_a_step_along_the_keys_lands_where_a_search_does(seed):
    """Runs of consecutive keys that start below every key, cross gaps and occupied stretches and run past the last
    key, and jumps between runs: each step gives the index a binary search gives."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    keys = torch.unique(torch.randint(10, 200, (60,), generator=g))  # sorted, unique, with gaps
    asked = torch.cat(
        [torch.arange(s, s + n) for s, n in zip(torch.randint(0, 230, (40,), generator=g).tolist(), [7, 1, 3, 12] * 10)]
    )
    asked = torch.cat([torch.arange(0, 15), asked, torch.arange(190, 215)])
    stepped = torch.zeros(asked.numel(), dtype=torch.int32)
    searched = torch.zeros_like(stepped)
    wp.launch(
        _walk, dim=1, inputs=[wp.from_torch(t) for t in (keys, asked, stepped, searched)], device="cpu"
    )  # fmt: skip
    assert torch.equal(stepped, searched)
    assert torch.equal(searched.long(), torch.searchsorted(keys, asked))


@pytest.mark.parametrize("seed", range(8))
def test_dense_summary_is_the_sorted_keys_summary(seed, monkeypatch):
    """Per-particle depths and ids as `surface_depth` hands them over (depth > 0 exactly where into ≥ 0; ties; ids up
    to DENSE_PAIRS; unlabelled particles; no particle behind a surface): the dense table's summary is the sorted
    keys' one, pairs in the same order, at a threshold equal to a depth and below every depth."""
    g = torch.Generator().manual_seed(seed)
    n, K = 400, [1, 2, 3, 5, 9, 17, 32, 2][seed]
    fragment = torch.randint(-1, K, (n,), generator=g)
    into = torch.randint(0, K, (n,), generator=g)
    behind = (torch.rand(n, generator=g) < (0.0 if seed == 7 else 0.3)) & (fragment >= 0) & (into != fragment)
    into = torch.where(behind, into, torch.full_like(into, -1))
    depth = torch.where(behind, torch.randint(1, 6, (n,), generator=g).double() * 1e-3, torch.zeros(n).double())
    cal = {"radius": 0.05, "filled": torch.ones(K, dtype=torch.float64), "spacing": 0.05 / pen.SPACINGS}
    monkeypatch.setattr(pen, "surface_depth", lambda *a, **k: (depth, into))
    x = torch.zeros(n, 3, dtype=torch.float64)
    for crossing_at in (0.0, 3e-3):
        dense = pen.surface_penetration(x, fragment, crossing_at, cal)
        monkeypatch.setattr(pen, "DENSE_PAIRS", -1)
        keyed = pen.surface_penetration(x, fragment, crossing_at, cal)
        monkeypatch.setattr(pen, "DENSE_PAIRS", 32)
        assert dense == keyed and list(dense["pairs"]) == list(keyed["pairs"])
        empty = {"depth": 0.0, "crossing": 0, "pairs": {}, "radius": 0.05}
        spread = pen._summary_dense(depth, fragment, into, crossing_at, K, empty, rows=7)
        assert spread == {**keyed, "radius": 0.05} and list(spread["pairs"]) == list(keyed["pairs"])
        assert (dense["crossing"] > 0) == (seed != 7 and bool((depth > crossing_at).any()))
