"""Per-fragment field metrics of a grid in two launches (the diagnostics' shadow transfer, each frame).

Over every node i and field k of the slot storage (`layout.py`), in float64:
    M_k = Σ_i m_i^k                                  (per-fragment grid mass, Eq. mass_error)
    E   = Σ_i Σ_k [m_i^k > ε_m] m_i^k ‖v̄_i − v_i^k‖²,  v̄_i = Σ_k p_i^k / Σ_k m_i^k,  v_i^k = p_i^k / m_i^k
                                                     (counterfactual mixing numerator, Eq. mixing)
    nodes with ≥ 1 and with ≥ 2 active fields (m > ε_m)   (shared support)
Only a pool row can hold a second field, so `dense_sums` runs over every node (slot 0; or a box holding every
node with mass: the nodes without add nothing, and the others add in the same order) and `pool_sums`
over the pool's rows. Each thread adds into one of `out`'s rows (thread index mod its row count), which
the host sums: a hundred thousand float64 atomics on the same few addresses would serialise on a GPU. The
torch twins, summing the same terms in another order, are `Grid.fragment_mass`
and `Grid.mixing`; `tests/test_many_fragments.py` compares the two. Replaces ~60 small torch ops a
frame with two launches.
"""

from __future__ import annotations

import warp as wp

from ..stencil import flat
from ..storage import MAX_SLOTS
from .layout import EMPTY_KEY, OWNER_MASK, GridView

wp.set_module_options({"enable_backward": False})

OUT_TOTAL, OUT_MIXING, OUT_ACTIVE, OUT_SHARED = range(4)  # then OUT_MASS + k for fragment k < K
OUT_MASS = 4

vec_sd = wp.types.vector(length=MAX_SLOTS, dtype=wp.float64)


@wp.kernel
def dense_sums(g: GridView, lo: wp.vec3i, eps_m: wp.float64, K: int, out: wp.array2d(dtype=wp.float64)):
    """Slot 0 of every node of the box launched from node `lo` (every node that may hold mass): total mass, its
    fragment's mass, nodes whose slot 0 is active."""
    i, j, l = wp.tid()  # noqa: E741
    n = flat(wp.vec3i(i + lo[0], j + lo[1], l + lo[2]), wp.vec3i(0, 0, 0), g.shape)
    m = g.mp[n][3]
    if m == 0.0:
        return
    b = n % out.shape[0]
    wp.atomic_add(out, b, OUT_TOTAL, wp.float64(m))
    f = (g.owner[n] & OWNER_MASK) - 1
    if f >= 0 and f < K:
        wp.atomic_add(out, b, OUT_MASS + f, wp.float64(m))
    if wp.float64(m) > eps_m:
        wp.atomic_add(out, b, OUT_ACTIVE, wp.float64(1.0))


@wp.kernel
def pool_sums(g: GridView, eps_m: wp.float64, K: int, out: wp.array2d(dtype=wp.float64)):
    """Each used pool row: its slots' mass (total and per fragment), the mixing of all the node's
    fields (slot 0 included), and the node's active-field count (added to `dense_sums`' count)."""
    r = wp.tid()
    n = g.key[r]
    if n == EMPTY_KEY:
        return
    S = g.slots
    b = r % out.shape[0]
    m = vec_sd()
    q0 = g.mp[n]
    m[0] = wp.float64(q0[3])
    P = wp.vec3d(wp.float64(q0[0]), wp.float64(q0[1]), wp.float64(q0[2]))
    M = m[0]
    active = int(0)  # noqa: UP018 (a dynamic Warp variable)
    if m[0] > eps_m:
        active = 1
    pool_mass = wp.float64(0.0)
    for s in range(1, S):
        f = g.pool_owner[r * (S - 1) + s - 1]
        if f >= 0:
            q = g.mp[g.n_nodes + r * (S - 1) + s - 1]
            m[s] = wp.float64(q[3])
            P = P + wp.vec3d(wp.float64(q[0]), wp.float64(q[1]), wp.float64(q[2]))
            M = M + m[s]
            pool_mass = pool_mass + m[s]
            if f < K:
                wp.atomic_add(out, b, OUT_MASS + f, m[s])
            if m[s] > eps_m:
                active = active + 1
    wp.atomic_add(out, b, OUT_TOTAL, pool_mass)
    if active >= 1 and not (m[0] > eps_m):
        wp.atomic_add(out, b, OUT_ACTIVE, wp.float64(1.0))  # slot 0 inactive: `dense_sums` did not count it
    if active >= 2:
        wp.atomic_add(out, b, OUT_SHARED, wp.float64(1.0))
    mixing = wp.float64(0.0)
    if M > wp.float64(0.0):  # an active field has m > ε_m ≥ 0: v̄ = P / M exactly, however light the node
        vbar = P / M
        for s in range(S):
            if m[s] > eps_m:
                q = q0
                if s > 0:
                    q = g.mp[g.n_nodes + r * (S - 1) + s - 1]
                v = wp.vec3d(wp.float64(q[0]), wp.float64(q[1]), wp.float64(q[2])) / m[s]
                mixing = mixing + m[s] * wp.length_sq(vbar - v)
    wp.atomic_add(out, b, OUT_MIXING, mixing)
