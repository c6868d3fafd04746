"""How the mass-gradient contact normals read a fragment's nodal mass from the slot storage
(`grid.normal_kernels.field_mass`, `pool_mass_gradients`), on a 5³ grid with 4 slots written by hand:

- fragment k's mass at a node is slot 0's when k owns slot 0; otherwise the pool slot k holds in the node's row;
  and 0 when the node has no row, when its row holds no slot of k, or when its owner word claims a row that the
  pool does not hold: an absent field has no mass, whatever sits in the buffers. A node outside the grid reads
  the nearest node inside it (clamped);
- a slot that no fragment owns (slot 0 with a free owner word, a pool slot whose owner is −1) has no field, so
  its gradient is exactly 0 even if its buffer holds mass; an owned slot gets the central difference of its own
  fragment's masses, ∂m/∂x = (m(i+1) − m(i−1)) / 2Δx."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import ROW_FLAG, GridView
from fracture_gs.sim.grid.normal_kernels import field_mass, pool_mass_gradients

N, DX, EPS = 5, 0.25, 1e-3


def _flat(i, j, l):  # noqa: E741
    return (i * N + j) * N + l


def _grid():
    """A 5³ grid with 4 slots and an empty pool of 256 rows; every node's slot 0 holds mass 1 + i (free owner)."""
    ensure_warp()
    g = Grid((0.0, 0.0, 0.0), DX, (N, N, N), "cpu", slots=4)
    g.ensure_pool(4)
    g.mp[..., 3] = 1.0 + torch.arange(N, dtype=torch.float32)[:, None, None]
    return g


def _add_row(g, n, owners, masses):
    """Give node n a pool row at its first probe (empty pool): slots 1-3 owned by `owners`, holding `masses`."""
    row = ((n * 1640531527) & 0x7FFFFFFF) & (g.capacity - 1)
    assert int(g.key[row]) == -1
    g.key[row] = n
    g._owner[n] |= ROW_FLAG
    for j, (o, m) in enumerate(zip(owners, masses)):
        g.pool_owner[row * 3 + j] = o
        g._mp[g.n_nodes + row * 3 + j, 3] = m
    return row


@wp.kernel
def _masses(g: GridView, nodes: wp.array(dtype=wp.vec3i), ks: wp.array(dtype=wp.int32), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = field_mass(g, nodes[i], ks[i])


def test_a_fragments_mass_is_its_own_slot_and_zero_where_it_has_no_field():
    """Node a: slot 0 owned by fragment 0. Node b: slot 0 fragment 0 (mass 3), a row with fragment 2 in slot 1 (mass
    7) and fragment 5 in slot 3 (mass 9). Node c: owner word says slot 0 is fragment 1's and that a row exists, but
    the pool holds none. Reads: a/0 → its slot 0; a/1 → 0 (no row); b/2 → 7; b/5 → 9; b/3 → 0 (not in the row);
    b/0 → 3; c/0 → 0 (no row found); c/1 → slot 0; (−1, 1, 1) and (5, 1, 1) read nodes (0, 1, 1) and (4, 1, 1)."""
    g = _grid()
    a, b, c = (1, 1, 1), (2, 3, 1), (3, 1, 2)
    g._owner[_flat(*a)] = 1
    g._owner[_flat(*b)] = 1
    g.mp[b][3] = 3.0
    _add_row(g, _flat(*b), [2, -1, 5], [7.0, 0.0, 9.0])
    g._owner[_flat(*c)] = 2 | ROW_FLAG
    g._owner[_flat(0, 1, 1)] = 4
    g._owner[_flat(4, 1, 1)] = 4
    queries = [(a, 0, 2.0), (a, 1, 0.0), (b, 2, 7.0), (b, 5, 9.0), (b, 3, 0.0), (b, 0, 3.0), (c, 0, 0.0), (c, 1, 4.0)]
    queries += [((-1, 1, 1), 3, 1.0), ((5, 1, 1), 3, 5.0)]
    nodes = wp.from_torch(torch.tensor([q[0] for q in queries], dtype=torch.int32), dtype=wp.vec3i)
    ks = wp.from_torch(torch.tensor([q[1] for q in queries], dtype=torch.int32))
    out = wp.zeros(len(queries), dtype=float, device="cpu")
    wp.launch(_masses, dim=len(queries), inputs=[g.view, nodes, ks, out], device="cpu")
    assert out.numpy().tolist() == [q[2] for q in queries]


def test_a_slot_no_fragment_owns_has_zero_gradient_even_holding_mass():
    """Node (2, 2, 2) has a row but a free slot 0 (mass 3 in its buffer) and pool slots owned by −1 (mass 1), 3
    (mass 2) and −1 (mass 0.5); the nodes around hold mass in free slot 0s, node (3, 2, 2)'s slot 0 is fragment 3's
    (mass 4). The free slots' gradients are exactly 0; fragment 3's is (4 − 0) / 2Δx along x (node (1, 2, 2) holds
    none of fragment 3) and 0 along y and z."""
    g = _grid()
    n = _flat(2, 2, 2)
    g.mp[2, 2, 2, 3] = 3.0
    g._owner[_flat(3, 2, 2)] = 4
    row = _add_row(g, n, [-1, 3, -1], [1.0, 2.0, 0.5])
    g.vel.fill_(7.0)  # stale values: every slot's gradient must be written
    g._vel[g.n_nodes :] = 7.0
    grad0 = torch.full((g.capacity, 3), 7.0)
    wp.launch(
        pool_mass_gradients,
        g.capacity * g.slots,
        [g.view, EPS, wp.from_torch(grad0, dtype=wp.vec3)],
        device="cpu",
    )
    assert grad0[row].tolist() == [0.0, 0.0, 0.0], "slot 0 has no owner"
    pool = g._vel[g.n_nodes + row * 3 : g.n_nodes + row * 3 + 3]
    assert pool[0].tolist() == [0.0, 0.0, 0.0] and pool[2].tolist() == [0.0, 0.0, 0.0], "free pool slots"
    assert pool[1].tolist() == [4.0 / (2 * DX), 0.0, 0.0]
