"""P2G's fan-out (`sim.grid.fanout_kernels.p2g_fanout`) and the G2P that reads its slot cache:

- thread t = 27 i + q deposits stencil node q of the i-th LISTED particle only (i < first[0]); the threads past
  the listed ones (the launch covers a capacity) deposit nothing, and the solo particles behind them in `order`
  are left to the dense P2G;
- a particle of a fragment that does not own slot 0 claims a pool slot at each of its 27 nodes, deposits its
  mass there (Σ w m = m), and keeps in cache[27 i + q] the buffer index it deposited into — the index
  `read_index` finds — and nothing else is written to the cache;
- G2P with `cached` = 1 gathers from exactly those cached indices: the particle gets its own field's velocity,
  as the lookup path (`cached` = 0) does, and not slot 0's.

An 8³ grid (Δx = 1/8) with 2 slots and a pool; slot 0 of every node is fragment 0's. Particle A (fragment 1,
1 kg) is listed, particle B (fragment 0, 2 kg, solo) follows it in `order`; the launches cover capacity 2."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fanout_kernels import LANES, g2p_fanout, p2g_fanout
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import ROW_FLAG
from fracture_gs.sim.storage import N_COUNTS

ensure_warp()
N, DX, DT = 8, 1 / 8, 1e-3
X = [(0.4, 0.45, 0.5), (0.3, 0.3, 0.3)]  # A (listed), B (solo)
CAP = 2


def _clock():
    c = FrameClock("cpu", 0)
    c.set(DT, [0.0])
    return c


def _ints(*a):
    return wp.from_torch(torch.tensor(a, dtype=torch.int32))


def _p2g():
    """The grid and the cache after one fan-out P2G of A and B (cache preset to −7)."""
    g = Grid((0.0, 0.0, 0.0), DX, (N, N, N), "cpu", slots=2)
    g.ensure_pool(64)
    g._owner.fill_(1)  # fragment 0 holds slot 0 everywhere
    g.n_fields = 2
    x = torch.tensor(X)
    z3, z33 = torch.zeros(2, 3), torch.zeros(2, 3, 3)
    cache = torch.full((27 * CAP,), -7, dtype=torch.int32)
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    inputs = [wp.from_torch(x, dtype=wp.vec3), wp.from_torch(z3, dtype=wp.vec3), wp.from_torch(z33, dtype=wp.mat33)]
    inputs += [wp.from_torch(torch.tensor([1.0, 2.0])), wp.from_torch(torch.full((2,), 1e-6))]
    inputs += [wp.from_torch(z33.clone(), dtype=wp.mat33), _ints(1, 0), _ints(0, 0), _ints(0, 1), _ints(1)]
    inputs += [wp.from_torch(cache), _clock().view, g.view, wp.from_torch(counts)]
    wp.launch(p2g_fanout, dim=27 * CAP, inputs=inputs, device="cpu")
    assert int(counts.abs().sum()) == 0, "no overflow"
    return g, cache


def _stencil_nodes(x):
    base = [int(torch.floor(torch.tensor(c / DX - 0.5))) for c in x]
    return [((base[0] + i) * N + base[1] + j) * N + base[2] + l for i in range(3) for j in range(3) for l in range(3)]


def test_the_fanout_deposits_the_listed_particle_into_its_pool_slots_and_caches_them():
    """A's 1 kg lands in pool slots (slot 0 holds no mass at all: B is not the fan-out's), at one claimed row per
    stencil node; cache entries 0 … 26 are the pool buffer indices of A's nodes in stencil order (each holding
    that node's mass w m > 0), entries 27 … 53 (past the listed particle) keep −7."""
    g, cache = _p2g()
    n = g.n_nodes
    assert float(g._mp[:n, 3].abs().sum()) == 0.0, "slot 0 untouched"
    assert abs(float(g._mp[n:, 3].sum()) - 1.0) < 1e-6
    assert cache[27:].tolist() == [-7] * 27
    want = []
    for node in _stencil_nodes(X[0]):
        assert int(g._owner[node]) & ROW_FLAG, "a row was claimed"
        row = int(torch.nonzero(g.key == node).flatten()[0])
        assert int(g.pool_owner[row]) == 1
        want.append(n + row)
    assert cache[:27].tolist() == want
    assert bool((g._mp[cache[:27].long(), 3] > 0).all())


def _g2p(g, cache, cached):
    """A's velocity after one fan-out G2P (coop = 0), its pool slots moving at (1, −1, 2), slot 0 at (5, 5, 5)."""
    n = g.n_nodes
    g._vel[:n] = torch.tensor([5.0, 5.0, 5.0])
    g._vel[n:] = torch.tensor([1.0, -1.0, 2.0])
    x = torch.tensor(X)
    v, C, F = torch.full((2, 3), 7.0), torch.zeros(2, 3, 3), torch.eye(3).repeat(2, 1, 1)
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    inputs = [wp.from_torch(x, dtype=wp.vec3), wp.from_torch(v, dtype=wp.vec3), wp.from_torch(C, dtype=wp.mat33)]
    inputs += [wp.from_torch(F, dtype=wp.mat33), _ints(1, 0), _ints(0, 1), _ints(1), wp.from_torch(cache), cached, 0]
    inputs += [_clock().view, g.view, wp.vec3(0.0, 0.0, 0.0), wp.vec3(1.0, 1.0, 1.0), wp.from_torch(counts)]
    inputs += [_ints(0, 1), 0]
    wp.launch(g2p_fanout, dim=LANES * CAP, inputs=inputs, device="cpu")
    assert v[1].tolist() == [7.0, 7.0, 7.0], "the solo particle is not the listed gather's"
    return v[0]


def test_g2p_reads_the_cached_slots_like_the_lookup_does():
    """After the fan-out P2G, G2P from the cache (cached = 1) and by lookup (cached = 0) both give A its own field's
    velocity (1, −1, 2), not slot 0's (5, 5, 5); with a cache that points at slot 0 instead, the cached gather
    follows the cache (so it is the cache that is read)."""
    g, cache = _p2g()
    for cached in (1, 0):
        torch.testing.assert_close(_g2p(g, cache, cached), torch.tensor([1.0, -1.0, 2.0]), rtol=0, atol=1e-6)
    to_slot0 = torch.tensor(_stencil_nodes(X[0]) + [0] * 27, dtype=torch.int32)
    torch.testing.assert_close(_g2p(g, to_slot0, 1), torch.tensor([5.0, 5.0, 5.0]), rtol=0, atol=1e-5)
