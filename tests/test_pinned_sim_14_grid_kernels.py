"""Slot-storage transfer kernels (`sim.grid.kernels`) launched directly on small grids, against hand rules:

- `clear_dense` zeroes slot 0's accumulators over exactly the active box it is launched on (offset by the box's
  origin on each axis by that axis's own coordinate), and `clear_pool` zeroes the band and pool accumulators of
  the used rows only, leaving the claims (keys, slot owners) and free rows alone;
- P2G counts a particle as escaped when ANY node of its 3×3×3 stencil lies outside the active box [lo, hi), at
  either end of an axis, once per particle;
- a band particle deposits its band mass w·m at every stencil node, also where the node's pool row is row 0 of
  the pool (a valid row), so a band particle's band mass equals its mass deposit node by node;
- a full pool counts one pool overflow per failed deposit (27 for one band particle), and the deposits still
  land in slot 0 (mass conserved);
- a fragment that finds every slot of a node's row taken deposits into slot 0 (merged, mass kept) and counts one
  slot overflow per such deposit; the owner of slot 0 itself, band particle or not, never counts one;
- the paper's contact gate needs both fields' band mass strictly above ε_band: a field at exactly ε_band, in
  either slot, is not in contact.

Grids of 5³-8³ nodes on the CPU; values are exact in float32 where compared exactly."""

import torch
import warp as wp
from simutil import fill_slots

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import clear_dense, clear_pool, grid_update_pool, p2g
from fracture_gs.sim.grid.layout import EMPTY_KEY
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.physics.contact import NORMAL_LATCHED
from fracture_gs.sim.storage import COUNT_ESCAPED, COUNT_POOL_OVERFLOW, COUNT_SLOT_OVERFLOW, N_COUNTS

ensure_warp()
DT = 1e-3


def _clock():
    c = FrameClock("cpu", 0)
    c.set(DT, [0.0])
    return c


def test_clear_dense_zeroes_exactly_the_box_it_is_launched_on():
    """A 6×7×8 grid of ones; a 2×3×4 launch at origin (1, 2, 3) zeroes nodes [1, 3) × [2, 5) × [3, 7) and no other."""
    g = Grid((0.0, 0.0, 0.0), 0.1, (6, 7, 8), "cpu")
    g._mp.fill_(1.0)
    wp.launch(clear_dense, dim=(2, 3, 4), inputs=[g.view, wp.vec3i(1, 2, 3)], device="cpu")
    want = torch.ones(6, 7, 8, 4)
    want[1:3, 2:5, 3:7] = 0.0
    assert torch.equal(g.mp, want)


def test_clear_pool_zeroes_the_used_rows_accumulators_and_keeps_the_claims():
    """Two fields in every node's row of a 5³ grid (3 slots), then one row freed: after `clear_pool` every used
    row's band (all slots) and pool (p, m) are 0, slot 0's dense (p, m) and every key and slot owner are as
    before, and the freed row's band and pool entries keep their values."""
    g = Grid((0.0, 0.0, 0.0), 0.2, (5, 5, 5), "cpu", slots=3)
    g.ensure_pool(125)
    m = torch.ones(2, 5, 5, 5, dtype=torch.float64)
    fill_slots(g, m, torch.ones(2, 5, 5, 5, 3, dtype=torch.float64))
    free = int(torch.nonzero(g.key == 7).flatten()[0])
    g.key[free] = EMPTY_KEY
    s1 = g.slots - 1
    g._mp[g.n_nodes + free * s1 + 1] = 3.0
    keys, owners, dense = g.key.clone(), g.pool_owner.clone(), g._mp[: g.n_nodes].clone()
    wp.launch(clear_pool, dim=g.capacity, inputs=[g.view], device="cpu")
    used = g.key >= 0
    band = g.band.view(g.capacity, g.slots)
    pool = g._mp[g.n_nodes :].view(g.capacity, s1, 4)
    assert not bool(band[used].any()) and not bool(pool[used].any())
    assert band[free].tolist() == [1.0, 1.0, 0.0]
    assert pool[free].tolist() == [[1.0, 1.0, 1.0, 1.0], [3.0, 3.0, 3.0, 3.0]]
    assert torch.equal(g.key, keys) and torch.equal(g.pool_owner, owners) and torch.equal(g._mp[: g.n_nodes], dense)


def _p2g(g, x, fragment, band, multifield, lo, hi):
    """One P2G launch of particles at rest (m = 1 kg, V = 1e−3 m³, no stress) at x; returns the counters."""
    n = len(x)
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    zeros3, zeros33 = torch.zeros(n, 3), torch.zeros(n, 3, 3)
    inputs = [
        wp.from_torch(x.float().contiguous(), dtype=wp.vec3),
        wp.from_torch(zeros3, dtype=wp.vec3),
        wp.from_torch(zeros33, dtype=wp.mat33),
        wp.from_torch(torch.ones(n)),
        wp.from_torch(torch.full((n,), 1e-3)),
        wp.from_torch(zeros33.clone(), dtype=wp.mat33),
        wp.from_torch(torch.tensor(fragment, dtype=torch.int32)),
        wp.from_torch(torch.tensor(band, dtype=torch.int32)),
        wp.from_torch(torch.zeros(n, dtype=torch.int32)),  # no particle is solo
        multifield,
        -1,
        0,
        _clock().view,
        g.view,
        wp.vec3i(*lo),
        wp.vec3i(*hi),
        wp.from_torch(counts),
    ]
    wp.launch(p2g, dim=n, inputs=inputs, device="cpu")
    return counts


def test_p2g_counts_a_particle_whose_stencil_leaves_the_active_box_at_either_end():
    """Active box [2, 6)³ of an 8³ grid (Δx = 1/8). Stencil bases (2, 2, 2) and (3, 3, 3) lie inside (nodes 2 … 5);
    base (3, 3, 4) reaches node 6 on z (top end), base (1, 3, 3) starts at node 1 on x (bottom end), base (4, 1, 4)
    both on y and z: three escapes, each counted once."""
    g = Grid((0.0, 0.0, 0.0), 1 / 8, (8, 8, 8), "cpu")
    bases = torch.tensor([[2, 2, 2], [3, 3, 3], [3, 3, 4], [1, 3, 3], [4, 1, 4]], dtype=torch.float64)
    x = (bases + 1.0) / 8  # at the stencil's centre node: base = floor(x/Δx − 0.5)
    counts = _p2g(g, x, [0] * 5, [0] * 5, 0, (2, 2, 2), (6, 6, 6))
    assert int(counts[COUNT_ESCAPED]) == 3
    counts = _p2g(g, x[:2], [0] * 2, [0] * 2, 0, (2, 2, 2), (6, 6, 6))
    assert int(counts[COUNT_ESCAPED]) == 0


def test_a_band_particle_deposits_band_mass_also_through_pool_row_zero():
    """A band particle (fragment 0, m = 1 kg) at (0.1, 0.11, 0.12) on an 8³ multi-field grid: stencil base (0, 0, 0),
    whose node 0 hashes to pool row 0. Every stencil node's band mass equals its mass deposit w·m (node 0's too,
    kept in row 0), and both sum to 1 kg."""
    g = Grid((0.0, 0.0, 0.0), 1 / 8, (8, 8, 8), "cpu", slots=2)
    g.ensure_pool(64)
    g.n_fields = 1
    counts = _p2g(g, torch.tensor([[0.1, 0.11, 0.12]]), [0], [1], 1, (0, 0, 0), (8, 8, 8))
    assert int(counts.abs().sum()) == 0
    assert int(g.key[0]) == 0, "node 0 holds pool row 0"
    mass, band = g.mass[0].double(), g.band_mass[0].double()
    assert float(mass[0, 0, 0]) > 0.005
    assert torch.allclose(band, mass, rtol=0, atol=1e-7)
    assert abs(float(band.sum()) - 1.0) < 1e-6


def test_a_full_pool_counts_one_overflow_per_failed_deposit_and_keeps_the_mass():
    """Every pool row taken by node 511 (outside the stencil): a band particle's 27 row claims all fail — 27 pool
    overflows, not more — and its 1 kg still lands in slot 0."""
    g = Grid((0.0, 0.0, 0.0), 1 / 8, (8, 8, 8), "cpu", slots=2)
    g.ensure_pool(64)
    g.key.fill_(511)
    g.n_fields = 1
    counts = _p2g(g, torch.tensor([[0.3, 0.3, 0.3]]), [0], [1], 1, (0, 0, 0), (8, 8, 8))
    assert int(counts[COUNT_POOL_OVERFLOW]) == 27
    assert abs(float(g._mp[: g.n_nodes, 3].double().sum()) - 1.0) < 1e-6


def test_a_third_fragment_on_two_slots_merges_into_slot_0_and_counts_each_deposit():
    """Three particles of 1 kg at one point of an 8³ grid with 2 slots, fragments 0, 1, 2 in launch order (the CPU
    runs threads in order): fragment 0 claims slot 0 at its 27 nodes, fragment 1 the pool slot, fragment 2 finds
    none — 27 slot overflows, its mass in slot 0 (field 0 holds 2 kg, field 1 1 kg, field 2 nothing). A band
    particle of fragment 0 then deposits into its own slot 0: no overflow, 3 kg in field 0."""
    g = Grid((0.0, 0.0, 0.0), 1 / 8, (8, 8, 8), "cpu", slots=2)
    g.ensure_pool(64)
    g.n_fields = 3
    x = torch.tensor([[0.3, 0.3, 0.3]] * 3)
    counts = _p2g(g, x, [0, 1, 2], [0, 0, 0], 1, (0, 0, 0), (8, 8, 8))
    assert counts.tolist()[COUNT_SLOT_OVERFLOW] == 27 and int(counts.abs().sum()) == 27
    assert [round(float(f), 5) for f in g.mass.double().sum((1, 2, 3))] == [2.0, 1.0, 0.0]
    counts = _p2g(g, x[:1], [0], [1], 1, (0, 0, 0), (8, 8, 8))
    assert int(counts.abs().sum()) == 0
    assert [round(float(f), 5) for f in g.mass.double().sum((1, 2, 3))] == [3.0, 1.0, 0.0]


def test_the_band_gate_needs_both_fields_strictly_above_eps_band():
    """Two equal-mass fields approaching along the latched normal +z (v⁰ = (0, 0, 1), v¹ = (0, 0, −1)) at every
    node of a 5³ grid, ε_band = 0.25. Band masses (b⁰, b¹): (0.5, 0.25) and (0.25, 0.5) are not in contact (both
    keep their velocity); (0.5, next float above 0.25) is, and the inelastic projection stops both fields."""
    g = Grid((0.0, 0.0, 0.0), 0.2, (5, 5, 5), "cpu", slots=2)
    g.ensure_pool(125)
    m = torch.ones(2, 5, 5, 5, dtype=torch.float64)
    v = torch.zeros(2, 5, 5, 5, 3, dtype=torch.float64)
    v[0, ..., 2], v[1, ..., 2] = 1.0, -1.0
    above = float(torch.nextafter(torch.tensor(0.25), torch.tensor(1.0)))
    band = torch.full((2, 5, 5, 5), 0.5, dtype=torch.float64)
    band[1, 0], band[0, 1], band[1, 2] = 0.25, 0.25, above  # i = 0, 1, 2; i = 3, 4 both 0.5
    fill_slots(g, m, v, band)
    colliders = Boundaries([], "cpu", (5, 5, 5), 0).colliders
    cen = wp.from_torch(torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), dtype=wp.vec3)
    grad0 = wp.zeros(g.capacity, dtype=wp.vec3, device="cpu")
    inputs = [g.view, 1e-6, 0.25, 0.0, 1, 1, NORMAL_LATCHED, wp.vec3(0.0, 0.0, 1.0), cen, 0.0, 0.0, _clock().view]
    inputs += [wp.vec3(0.0, 0.0, 0.0), colliders, 0, g.wp["stats"], g.wp["pair_stats"], g.pair_fragments, grad0]
    wp.launch(grid_update_pool, dim=g.capacity, inputs=inputs, device="cpu")
    vz = g.velocity[..., 2].double()  # [2, 5, 5, 5]
    for i, contact in ((0, False), (1, False), (2, True), (3, True), (4, True)):
        want = (0.0, 0.0) if contact else (1.0, -1.0)
        assert vz[0, i].unique().tolist() == [want[0]] and vz[1, i].unique().tolist() == [want[1]], i
