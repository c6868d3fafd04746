"""The mass-gradient normals (`sim.grid.normal_kernels`) read a node's pool row only when the node's owner word
carries ROW_FLAG — the same test G2P's `read_index` makes — so the normals and G2P see one storage: at a node
without the flag the only field is slot 0's, whatever keys or masses the pool holds for it.

A 5³ grid (Δx = 1/4) with 4 slots and an empty pool; fragment 3's mass gradient at node (2, 2, 2) by central
differences, ∂m/∂x = (m(3, 2, 2) − m(1, 2, 2)) / 2Δx, with a pool row for node (3, 2, 2) that holds fragment 3
but whose owner word has no flag."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import ROW_FLAG
from fracture_gs.sim.grid.normal_kernels import pool_mass_gradients

N, DX, EPS = 5, 0.25, 1e-3


def _flat(i, j, l):  # noqa: E741
    return (i * N + j) * N + l


def _row(g, node, owners, masses, flag=True):
    """A pool row for `node` at its first probe: slots 1-3 owned by `owners`, holding `masses`; the owner word
    gets ROW_FLAG only with `flag`."""
    n = _flat(*node)
    row = ((n * 1640531527) & 0x7FFFFFFF) & (g.capacity - 1)
    assert int(g.key[row]) == -1, "first probe free"
    g.key[row] = n
    if flag:
        g._owner[n] |= ROW_FLAG
    for j, (o, m) in enumerate(zip(owners, masses)):
        g.pool_owner[row * 3 + j] = o
        g._mp[g.n_nodes + row * 3 + j, 3] = m
    return row


def _gradients(flag_right):
    ensure_warp()
    g = Grid((0.0, 0.0, 0.0), DX, (N, N, N), "cpu", slots=4)
    g.ensure_pool(4)
    for node in ((1, 2, 2), (2, 2, 2), (3, 2, 2)):
        g._owner[_flat(*node)] = 1  # fragment 0 holds slot 0 (mass 0.5)
        g.mp[node][3] = 0.5
    left = _row(g, (1, 2, 2), [3, -1, -1], [1.0, 0.0, 0.0])
    mid = _row(g, (2, 2, 2), [-1, 3, -1], [0.0, 2.0, 0.0])
    _row(g, (3, 2, 2), [3, -1, -1], [4.0, 0.0, 0.0], flag=flag_right)
    g.vel.fill_(7.0)
    g._vel[g.n_nodes :] = 7.0
    grad0 = torch.full((g.capacity, 3), 7.0)
    wp.launch(
        pool_mass_gradients, g.capacity * g.slots, [g.view, EPS, wp.from_torch(grad0, dtype=wp.vec3)], device="cpu"
    )
    pool = lambda row, s: g._vel[g.n_nodes + row * 3 + s - 1].tolist()  # noqa: E731
    return pool(mid, 2), pool(left, 1), grad0[mid].tolist()


def test_a_row_without_the_owner_flag_holds_no_field_for_the_normals():
    """Without the flag at (3, 2, 2), fragment 3 has no mass there: ∂m/∂x at (2, 2, 2) = (0 − 1)/(2 · ¼) = −2;
    with the flag its row's mass 4 counts: (4 − 1)/(2 · ¼) = 6. Along y and z no neighbour holds fragment 3: 0.
    Fragment 0's slot-0 gradient at (2, 2, 2) is 0 on x either way (0.5 on both sides)."""
    got, left, slot0 = _gradients(flag_right=False)
    assert got == [-2.0, 0.0, 0.0]
    assert slot0 == [0.0, 0.0, 0.0]
    got, _, _ = _gradients(flag_right=True)
    assert got == [6.0, 0.0, 0.0]
    # at (1, 2, 2): fragment 3 has mass 2 at (2, 2, 2) and none at (0, 2, 2): (2 − 0)/(2 · ¼) = 4
    assert left == [4.0, 0.0, 0.0]
