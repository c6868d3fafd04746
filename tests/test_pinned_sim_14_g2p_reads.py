"""G2P on the slot storage (`sim.grid.kernels.g2p`) reads each particle's own field, wherever the storage keeps it:

- a particle of the fragment holding slot 0 at its whole stencil reads slot 0 (the unrolled dense gather);
- a particle of a fragment held in a pool slot reads that slot at every node, and an affine field a + B x comes
  back exactly (APIC): v_p = a + B x_p, C_p = B, F ← (I + Δt B) F, x ← x + Δt v_p;
- a fragment with no slot at a node (its deposits merged into slot 0), a node without a pool row (also within a
  stencil whose other nodes have rows: node by node), a solo particle, and every particle of a single-field
  transfer read slot 0;
- the per-fragment pass (`only_fragment`) moves that fragment's particles only.

An 8³ grid (Δx = 1/8), three slots: field 0 (slot 0) moves at (1, 0, 0), field 1 (pool slot 1) at
(0.5 y, 2, 0.25 x), fragment 2 has no slot anywhere, and the nodes i ≥ 5 have no row flag."""

import torch
import warp as wp
from simutil import fill_slots

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import g2p
from fracture_gs.sim.grid.layout import ROW_FLAG
from fracture_gs.sim.storage import N_COUNTS

ensure_warp()
N, DX, DT = 8, 1 / 8, 2.0**-10
B = torch.tensor([[0.0, 0.5, 0.0], [0.0, 0.0, 0.0], [0.25, 0.0, 0.0]], dtype=torch.float64)
A = torch.tensor([0.0, 2.0, 0.0], dtype=torch.float64)
SLOT0 = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
# (position, fragment, solo): fragment 0, fragment 1, fragment 2 (no slot), fragment 1 where nodes have no row,
# fragment 1 solo
PARTICLES = [((0.3, 0.3, 0.3), 0, 0), ((0.3, 0.3, 0.3), 1, 0), ((0.3, 0.3, 0.3), 2, 0), ((0.8, 0.4, 0.4), 1, 0)]
PARTICLES += [((0.3, 0.3, 0.3), 1, 1), ((0.5, 0.3, 0.3), 1, 0)]  # and fragment 1 across the row border


def _grid():
    g = Grid((0.0, 0.0, 0.0), DX, (N, N, N), "cpu", slots=3)
    g.ensure_pool(N**3)
    idx = torch.stack(torch.meshgrid(*[torch.arange(N, dtype=torch.float64)] * 3, indexing="ij"), -1) * DX
    v = torch.zeros(3, N, N, N, 3, dtype=torch.float64)
    v[0] = SLOT0
    v[1] = A + idx @ B.T
    v[2] = torch.tensor([9.0, 9.0, 9.0], dtype=torch.float64)
    fill_slots(g, torch.ones(3, N, N, N, dtype=torch.float64), v)
    g._vel.copy_(g._mp[:, :3] / g._mp[:, 3:])  # the grid update's result: v = p/m
    g.pool_owner.view(-1, 2)[:, 1] = -1  # fragment 2 holds no pool slot: it merged into slot 0
    g._owner.view(N, N, N)[5:] &= ~ROW_FLAG
    g.n_fields = 3
    return g


def _g2p(multifield=1, only_fragment=-1):
    """(x, v, C, F) of the particles after one G2P (v, C preset to 7, F = I)."""
    g = _grid()
    n = len(PARTICLES)
    x = torch.tensor([p[0] for p in PARTICLES])
    v, C, F = torch.full((n, 3), 7.0), torch.full((n, 3, 3), 7.0), torch.eye(3).repeat(n, 1, 1)
    frag = torch.tensor([p[1] for p in PARTICLES], dtype=torch.int32)
    solo = torch.tensor([p[2] for p in PARTICLES], dtype=torch.int32)
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    arrays = [wp.from_torch(x, dtype=wp.vec3), wp.from_torch(v, dtype=wp.vec3), wp.from_torch(C, dtype=wp.mat33)]
    arrays += [wp.from_torch(F, dtype=wp.mat33), wp.from_torch(frag), wp.from_torch(solo)]
    order = wp.from_torch(torch.arange(n, dtype=torch.int32))
    first = wp.from_torch(torch.tensor([n], dtype=torch.int32))
    cache = wp.zeros(1, dtype=wp.int32, device="cpu")
    counts = wp.zeros(N_COUNTS, dtype=wp.int32, device="cpu")
    lo, hi = wp.vec3(0.0, 0.0, 0.0), wp.vec3(1.0, 1.0, 1.0)
    inputs = arrays + [order, first, 0, 0, cache, 0, multifield, only_fragment, clock.view, g.view, lo, hi, counts]
    wp.launch(g2p, dim=n, inputs=inputs, device="cpu")
    assert int(counts.numpy().sum()) == 0
    return x.double(), v.double(), C.double(), F.double()


def _check(p, x, v, C, F, vel, grad):
    """Particle p moved with velocity `vel` and velocity gradient `grad` (APIC: C = ∇v for an affine field)."""
    x0 = torch.tensor(PARTICLES[p][0], dtype=torch.float32).double()
    torch.testing.assert_close(v[p], vel, rtol=0, atol=2e-6)
    torch.testing.assert_close(C[p], grad, rtol=0, atol=2e-5)
    torch.testing.assert_close(F[p], torch.eye(3, dtype=torch.float64) + DT * grad, rtol=0, atol=1e-7)
    torch.testing.assert_close(x[p], x0 + DT * vel, rtol=0, atol=1e-7)


def test_each_particle_reads_its_own_field_where_the_storage_keeps_it():
    """Fragment 0 and fragment 2 (no slot), fragment 1 where no row is flagged, and the solo particle read slot 0;
    fragment 1 reads the affine field of its pool slot: v = (0.15, 2, 0.075), C = B, F = I + Δt B."""
    x, v, C, F = _g2p()
    zero = torch.zeros(3, 3, dtype=torch.float64)
    for p in (0, 2, 3, 4):
        _check(p, x, v, C, F, SLOT0, zero)
    xp = torch.tensor(PARTICLES[1][0], dtype=torch.float32).double()
    _check(1, x, v, C, F, A + B @ xp, B)


def _spline(f):
    """Quadratic B-spline weights of the three nodes base, base + 1, base + 2 at f = x/Δx − base."""
    return [0.5 * (1.5 - f) ** 2, 0.75 - (f - 1.0) ** 2, 0.5 * (f - 0.5) ** 2]


def test_a_stencil_across_the_row_border_reads_each_node_where_its_field_is():
    """Fragment 1 at (0.5, 0.3, 0.3): stencil nodes i = 3, 4 have rows (its pool slot: the affine field) and i = 5
    has none (slot 0: (1, 0, 0)), so v = Σ w_i v_i with v_i taken node by node (x weights 1/8, 3/4, 1/8)."""
    x, v, _, _ = _g2p()
    xp = torch.tensor(PARTICLES[5][0], dtype=torch.float64)
    base = torch.floor(xp / DX - 0.5)
    w = [_spline(float(xp[a] / DX - base[a])) for a in range(3)]
    want = torch.zeros(3, dtype=torch.float64)
    for i in range(3):
        for j in range(3):
            for k in range(3):
                node = base + torch.tensor([i, j, k], dtype=torch.float64)
                vi = SLOT0 if node[0] >= 5 else A + B @ (node * DX)
                want += w[0][i] * w[1][j] * w[2][k] * vi
    assert abs(float(want[0]) - float((A + B @ xp)[0])) > 0.05, "the two fields differ here"
    torch.testing.assert_close(v[5], want, rtol=0, atol=2e-6)
    torch.testing.assert_close(x[5], xp + DT * want, rtol=0, atol=1e-7)


def test_a_single_field_transfer_reads_slot_0_for_everyone():
    """multifield = 0: every particle, of any fragment, moves with slot 0's (1, 0, 0)."""
    x, v, C, F = _g2p(multifield=0)
    for p in range(len(PARTICLES)):
        _check(p, x, v, C, F, SLOT0, torch.zeros(3, 3, dtype=torch.float64))


def test_the_per_fragment_pass_moves_only_its_fragment():
    """only_fragment = 1: the three particles of fragment 1 are updated; fragments 0 and 2 keep v = 7 and x."""
    x, v, C, F = _g2p(only_fragment=1)
    for p in (0, 2):
        assert v[p].tolist() == [7.0] * 3 and x[p].tolist() == list(torch.tensor(PARTICLES[p][0]).double().tolist())
    xp = torch.tensor(PARTICLES[1][0], dtype=torch.float32).double()
    _check(1, x, v, C, F, A + B @ xp, B)
    _check(3, x, v, C, F, SLOT0, torch.zeros(3, 3, dtype=torch.float64))
