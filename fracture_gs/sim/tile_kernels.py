"""P2G of the dense-path particles through a block-shared node tile (GPU MLS-MPM's shared-memory P2G:
Gao et al. 2018, "GPU optimization of material point methods"; Taichi's block-local storage).

Each block of threads takes `block_dim` consecutive particles; particles sorted along a Morton curve of
their cells (`neighbourhood.cell_order(mode="morton")`) sit in a few neighbouring cells, so their
stencils fit a TILE³ node tile whose corner is the block's lowest stencil base. The same deposits as
`transfer_kernels.p2g`'s dense path (Eq. multifield_p2g, slot 0),
m_i += w m_p,  p_i += w m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w,
go into the tile with shared-memory atomics; the block then adds each non-zero tile node to the grid
with one global reduction. A deposit outside the tile goes to the grid directly, so any particle order
is correct (only slower). A warp's lanes take particles block_dim/32 apart, so few lanes of a warp add to
the same tile node at once. On the CPU a block has one lane unless `wp.config.enable_cpu_blocks` is set:
then each particle's tile holds its own stencil and every deposit is added to the grid in the same order
as `p2g` (bitwise the same fields).

Particles that are not solo on a multi-field grid are left to `fanout_kernels.p2g_fanout` (the host
takes this kernel only with it, and never for the global fragment pass).
"""

from __future__ import annotations

import warp as wp

from .clock import Clock, clock_dt
from .layout import COUNT_ESCAPED, GridView, flat, inside
from .transfer_kernels import atomic_add_vec4, node_terms, stencil

wp.set_module_options({"enable_backward": False})

TILE = 8  # nodes per axis of a block's tile: 8³ vec4 = 8 KiB of shared memory
FAR = 1 << 28  # stencil base of a lane with no particle (never the block's lowest)


@wp.func
def tile_particle(block: int, lane: int, bd: int):
    """Particle of (block, lane): lanes of one warp take particles bd/32 apart (consecutive when bd < 32)."""
    width = wp.min(bd, 32)
    return block * bd + (lane % width) * (bd // width) + lane // width


@wp.kernel
def p2g_tiled(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ (band-released)
    solo: wp.array(dtype=wp.int32),  # [N] 1: dense slot 0 on a multi-field grid
    multifield: int,
    clock: Clock,  # Δt
    g: GridView,
    lo: wp.vec3i,  # active box [lo, hi): a stencil outside it is counted (the frame is redone)
    hi: wp.vec3i,
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS] running counters
):
    """`p2g`'s dense path through a shared TILE³ tile; every lane reaches every tile call (no early return)."""
    block, lane = wp.tid()
    bd = wp.block_dim()
    p = tile_particle(block, lane, bd)
    has = False
    base = wp.vec3i(FAR, FAR, FAR)
    f = wp.vec3(0.0)
    w = wp.mat33(0.0)
    dw = wp.mat33(0.0)
    value = wp.vec4(0.0)
    m = float(0.0)  # noqa: UP018 (a dynamic Warp variable)
    vp = wp.vec3(0.0)
    Cp = wp.mat33(0.0)
    force = wp.mat33(0.0)
    if p < x.shape[0]:
        base, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
        if not (inside(base, lo, hi) and inside(base + wp.vec3i(2, 2, 2), lo, hi)):
            wp.atomic_add(counts, COUNT_ESCAPED, 1)  # the grid update will not see it: `advance` redoes the frame
        has = multifield == 0 or solo[p] != 0
        if has:
            m = mass[p]
            vp = v[p]
            Cp = C[p]
            force = -clock_dt(clock) * volume[p] * stress[p]
        else:
            base = wp.vec3i(FAR, FAR, FAR)
    corner = wp.vec3i(
        wp.tile_min(wp.tile(base[0]))[0], wp.tile_min(wp.tile(base[1]))[0], wp.tile_min(wp.tile(base[2]))[0]
    )
    tile = wp.tile_zeros(shape=(TILE, TILE, TILE), dtype=wp.vec4, storage="shared")
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                r = base + wp.vec3i(i, j, l) - corner
                near = has and r[0] < TILE and r[1] < TILE and r[2] < TILE  # r ≥ 0: corner is the lowest base
                if has:
                    weight, grad, dpos = node_terms(i, j, l, f, w, dw, g.dx, g.inv_dx)
                    mom = weight * m * (vp + Cp * dpos) + force * grad
                    value = wp.vec4(mom[0], mom[1], mom[2], weight * m)
                    if not near:
                        atomic_add_vec4(g.mp, flat(base + wp.vec3i(i, j, l), wp.vec3i(0, 0, 0), g.shape), value)
                r = wp.vec3i(wp.clamp(r[0], 0, TILE - 1), wp.clamp(r[1], 0, TILE - 1), wp.clamp(r[2], 0, TILE - 1))
                wp.tile_scatter_add(tile, r[0], r[1], r[2], value, near)
    e = lane
    while e < TILE * TILE * TILE:  # one global reduction per tile node that received anything
        a = e // (TILE * TILE)
        b = (e // TILE) % TILE
        c = e % TILE
        q = tile[a, b, c]
        if q[0] != 0.0 or q[1] != 0.0 or q[2] != 0.0 or q[3] != 0.0:
            atomic_add_vec4(g.mp, flat(corner + wp.vec3i(a, b, c), wp.vec3i(0, 0, 0), g.shape), q)
        e += bd
