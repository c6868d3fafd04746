"""P2G of the dense-path particles in runs: a thread deposits `run` consecutive particles and sums in registers
those that share a stencil base, so particles sorted by their stencil's base node
(`neighbourhood.cell_order(mode="cell")`) reach each of their 27 nodes with one global reduction per run and
base instead of one per particle.

The same deposits as `kernels.p2g`'s dense path (Eq. multifield_p2g, slot 0):
m_i += Σ_p w_ip m_p,  p_i += Σ_p w_ip m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w_ip.
Any order is correct (a change of base flushes the sums); with run = 1 the fields are bitwise `p2g`'s, otherwise
they differ by the order of float32 sums. Particles that are not solo on a multi-field grid are left to
`fanout_kernels.p2g_fanout` (the host takes this kernel only with it, and never for the global fragment pass).
Measured on the Table 2 ficus (docs/benchmarks/history-2026-11.md, "P2G in runs"): each doubling of the run up to 8
shortened P2G, runs of 8 taking less than half the time of one particle per thread; a block-shared node tile was
several times slower (shared-memory float atomics compile to compare-and-swap loops).
"""

from __future__ import annotations

import warp as wp

from ..clock import Clock, clock_dt
from ..stencil import add_particle, atomic_add_vec4, flat, inside, stencil, stencil_sums
from ..storage import COUNT_ESCAPED
from .layout import GridView

wp.set_module_options({"enable_backward": False})


@wp.func
def flush_run(g: GridView, base: wp.vec3i, acc: stencil_sums):
    """Add a run's 27 node sums to the grid: one reduction per node."""
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                q = 9 * i + 3 * j + l
                n = flat(base + wp.vec3i(i, j, l), wp.vec3i(0, 0, 0), g.shape)
                atomic_add_vec4(g.mp, n, wp.vec4(acc[q, 0], acc[q, 1], acc[q, 2], acc[q, 3]))


@wp.kernel
def p2g_runs(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ (band-released)
    solo: wp.array(dtype=wp.int32),  # [N] 1: dense slot 0 on a multi-field grid
    multifield: int,
    run: int,  # consecutive particles per thread
    clock: Clock,  # Δt
    g: GridView,
    lo: wp.vec3i,
    hi: wp.vec3i,
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS] running counters
):
    """`p2g`'s dense path for `run` consecutive particles: those that share a stencil base are summed in
    registers and reach the grid as one reduction per node."""
    t = wp.tid()
    acc = stencil_sums()
    cur = wp.vec3i(-1, -1, -1)
    dt = clock_dt(clock)
    for p in range(t * run, wp.min(t * run + run, x.shape[0])):
        base, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
        if not (inside(base, lo, hi) and inside(base + wp.vec3i(2, 2, 2), lo, hi)):
            wp.atomic_add(counts, COUNT_ESCAPED, 1)  # the grid update will not see it: `advance` redoes the frame
        if multifield == 0 or solo[p] != 0:
            if base[0] != cur[0] or base[1] != cur[1] or base[2] != cur[2]:
                if cur[0] >= 0:
                    flush_run(g, cur, acc)
                acc = stencil_sums()
                cur = base
            force = -dt * volume[p] * stress[p]
            acc = add_particle(acc, f, w, dw, g.dx, g.inv_dx, mass[p], v[p], C[p], force)
    if cur[0] >= 0:
        flush_run(g, cur, acc)
