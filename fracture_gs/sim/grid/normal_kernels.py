"""Per-node contact normals from the fragments' mass gradients (multi-velocity-field MPM: Bardenhagen et
al. 2001; Homel & Herbold 2017): ∇m^k at a node by central differences of fragment k's nodal masses,
∂m^k/∂x_a ≈ (m^k(i + e_a) − m^k(i − e_a)) / 2Δx, where a neighbour's mass is found through the slot
storage (slot 0 if the fragment owns it, else the neighbour's pool row).

`pool_mass_gradients` computes them before the pool pass with one thread per (pool row, slot), so each
thread's chain is one field's six lookups, not a row's (up to 24 with 4 slots, serial). Slot 0's
gradient goes to a [capacity] buffer; a pool slot's to its velocity entry, which the pool pass reads
first and overwrites with the field's velocity last (nothing else reads it in between).
"""

from __future__ import annotations

import warp as wp

from ..stencil import flat, unflat
from .layout import EMPTY_KEY, OWNER_MASK, ROW_FLAG, GridView, field_index, find_pool_slot, find_row

wp.set_module_options({"enable_backward": False})


@wp.func
def field_mass(g: GridView, node: wp.vec3i, k: int):
    """Mass of fragment k's field at `node` (0 if absent; the node is clamped into the grid)."""
    c = wp.vec3i(
        wp.clamp(node[0], 0, g.shape[0] - 1), wp.clamp(node[1], 0, g.shape[1] - 1), wp.clamp(node[2], 0, g.shape[2] - 1)
    )
    n = flat(c, wp.vec3i(0, 0, 0), g.shape)
    word = g.owner[n]
    if (word & OWNER_MASK) == k + 1:
        return g.mp[n][3]
    if (word & ROW_FLAG) == 0:
        return 0.0
    row = find_row(g.key, n, g.mask)
    if row < 0:
        return 0.0
    j = find_pool_slot(g.pool_owner, row, g.slots, k)
    if j == 0:
        return 0.0
    return g.mp[field_index(n, row, j, g.n_nodes, g.slots)][3]


@wp.func
def mass_gradient(g: GridView, node: wp.vec3i, k: int):
    """∇m^k at `node` by central differences of fragment k's nodal masses [kg/m]."""
    out = wp.vec3(0.0)
    for a in range(3):
        e = wp.vec3i(0, 0, 0)
        e[a] = 1
        out[a] = (field_mass(g, node + e, k) - field_mass(g, node - e, k)) * (0.5 * g.inv_dx)
    return out


@wp.kernel
def pool_mass_gradients(g: GridView, eps_m: float, grad0: wp.array(dtype=wp.vec3)):
    """∇m of the field in slot s of pool row r, thread t = r·S + s (zero for an empty or massless slot)."""
    t = wp.tid()
    r = t // g.slots
    s = t - r * g.slots
    n = g.key[r]
    if n == EMPTY_KEY:
        return
    k = int(-1)  # noqa: UP018 (dynamic Warp variables, assigned in the branches)
    m = float(0.0)  # noqa: UP018
    i = int(n)  # noqa: UP018
    if s == 0:
        k = (g.owner[n] & OWNER_MASK) - 1
        m = g.mp[n][3]
    else:
        i = g.n_nodes + r * (g.slots - 1) + s - 1
        k = g.pool_owner[r * (g.slots - 1) + s - 1]
        m = g.mp[i][3]
    G = wp.vec3(0.0)
    if k >= 0 and m > eps_m:
        G = mass_gradient(g, unflat(n, g.shape), k)
    if s == 0:
        grad0[r] = G
    else:
        g.vel[i] = G
