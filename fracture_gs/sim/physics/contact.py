"""Contact between the fragment fields at one grid node (paper Eqs. impulse, contact_update; L2 removed).

For a pair of fields a < b (ordered by fragment id) with normal n pointing from a into b, the
relative normal velocity is u_n = (v_b − v_a)·n. Approaching fields (u_n < 0) get the normal
impulse J = −(1+e) u_n / (1/m_a + 1/m_b), applied equal and opposite (m_a v_a + m_b v_b is
unchanged), then a Coulomb tangential impulse that removes the tangential relative velocity up to
μ·J. Separating fields (u_n ≥ 0) get nothing; with μ = 0 the tangential relative motion is
untouched. At a node with more than two fields the pairs are projected one after another in slot
order (a Gauss–Seidel sweep); each pair conserves momentum, so the node does.

Normals: the latched plane's normal n_Π (the paper's binary case), or the multi-velocity-field
normal n_ab ∝ ∇m_b − ∇m_a from the fragments' band-mass gradients (Bardenhagen et al. 2001; Homel
& Herbold 2017), falling back to the direction between the fragments' centroids, then to n_Π,
where the gradient is degenerate.
"""

from __future__ import annotations

import warp as wp

NORMAL_LATCHED = 0
NORMAL_MASS_GRADIENT = 1

# contact statistics accumulated by the grid update (float32, indices into Grid.contact_stats)
STAT_GATED, STAT_PROJECTED, STAT_DPX, STAT_DPY, STAT_DPZ, STAT_PNORM, STAT_UN_AFTER, STAT_DVT, STAT_FIRST_T = range(9)
N_STATS = 9
# per fragment pair (a < b, row a·K + b of Grid.pair_stats)
PAIR_FIRST_T, PAIR_DPX, PAIR_DPY, PAIR_DPZ, PAIR_PNORM, PAIR_GATED = range(6)
N_PAIR_STATS = 6
PAIR_FRAGMENTS = 128  # per-pair statistics for fragments below this id (K² rows: 393 KB, not max_fragments²)
NEVER = 1e30  # a first-contact time before any contact


@wp.func
def contact_normal(
    mode: int,
    latched: wp.vec3,
    g_a: wp.vec3,
    g_b: wp.vec3,
    centroids: wp.array(dtype=wp.vec3),  # [K]
    k_a: int,
    k_b: int,
):
    """Unit normal from field a (fragment k_a, mass gradient g_a) into field b. The centroids are read only
    where the gradients are degenerate (their loads stood on every pair's path when passed as values)."""
    if mode == NORMAL_LATCHED:
        return latched
    d = g_b - g_a
    if wp.length(d) > 1e-6 * (wp.length(g_a) + wp.length(g_b)) + 1e-30:
        return wp.normalize(d)
    e = centroids[k_b] - centroids[k_a]
    if wp.length(e) > 0.0:
        return wp.normalize(e)
    return latched


@wp.func
def contact_projection(v0: wp.vec3, v1: wp.vec3, m0: float, m1: float, n: wp.vec3, e: float, mu: float):
    """Approach-only, momentum-conserving normal impulse with restitution e, then Coulomb friction μ."""
    un = wp.dot(v1 - v0, n)
    if un >= 0.0:
        return v0, v1
    J = -(1.0 + e) * un / (1.0 / m0 + 1.0 / m1)
    w0 = v0 - (J / m0) * n
    w1 = v1 + (J / m1) * n
    if mu > 0.0:
        u = w1 - w0
        ut = u - wp.dot(u, n) * n
        s = wp.length(ut)
        if s > 0.0:
            Jt = wp.min(s / (1.0 / m0 + 1.0 / m1), mu * J)
            t = ut / s
            w0 = w0 + (Jt / m0) * t
            w1 = w1 - (Jt / m1) * t
    return w0, w1


@wp.func
def record_contact(
    stats: wp.array(dtype=float),
    pair_stats: wp.array(dtype=float),
    pair: int,
    t: float,
    v0: wp.vec3,
    v1: wp.vec3,
    w0: wp.vec3,
    w1: wp.vec3,
    m0: float,
    m1: float,
    normal: wp.vec3,
    project: int,
):
    """Contact diagnostics of one gated pair at one node: count, first time, momentum change, residual
    approach speed, change of tangential relative velocity; the same per fragment pair."""
    wp.atomic_add(stats, STAT_GATED, 1.0)
    wp.atomic_min(stats, STAT_FIRST_T, t)
    if project != 0:
        wp.atomic_add(stats, STAT_PROJECTED, 1.0)
    before = m0 * v0 + m1 * v1
    dp = (m0 * w0 + m1 * w1) - before
    wp.atomic_add(stats, STAT_DPX, dp[0])
    wp.atomic_add(stats, STAT_DPY, dp[1])
    wp.atomic_add(stats, STAT_DPZ, dp[2])
    wp.atomic_add(stats, STAT_PNORM, wp.length(before))
    wp.atomic_max(stats, STAT_UN_AFTER, wp.max(0.0, -wp.dot(w1 - w0, normal)))
    rel_t_before = (v1 - v0) - wp.dot(v1 - v0, normal) * normal
    rel_t_after = (w1 - w0) - wp.dot(w1 - w0, normal) * normal
    wp.atomic_max(stats, STAT_DVT, wp.length(rel_t_after - rel_t_before))
    if pair >= 0:
        base = pair * N_PAIR_STATS
        wp.atomic_min(pair_stats, base + PAIR_FIRST_T, t)
        wp.atomic_add(pair_stats, base + PAIR_DPX, dp[0])
        wp.atomic_add(pair_stats, base + PAIR_DPY, dp[1])
        wp.atomic_add(pair_stats, base + PAIR_DPZ, dp[2])
        wp.atomic_add(pair_stats, base + PAIR_PNORM, wp.length(before))
        wp.atomic_add(pair_stats, base + PAIR_GATED, 1.0)


@wp.func
def contact_pair(
    v0: wp.vec3,
    v1: wp.vec3,
    m0: float,
    m1: float,
    normal: wp.vec3,
    restitution: float,
    friction: float,
    project: int,
    record: int,
    stats: wp.array(dtype=float),
    pair_stats: wp.array(dtype=float),
    frag0: int,
    frag1: int,
    n_fragments: int,
    t: float,
):
    """One gated pair of fields at a node, field 0 the lower fragment id: if they approach along `normal`,
    the projection (with `project`) and the statistics (with `record`); returns the two velocities."""
    w0 = v0
    w1 = v1
    if wp.dot(v1 - v0, normal) < 0.0:
        if project != 0:
            w0, w1 = contact_projection(v0, v1, m0, m1, normal, restitution, friction)
        if record != 0:
            pair = -1
            if frag1 < n_fragments:
                pair = frag0 * n_fragments + frag1
            record_contact(stats, pair_stats, pair, t, v0, v1, w0, w1, m0, m1, normal, project)
    return w0, w1
