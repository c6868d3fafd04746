"""Fields in dense boxes, one per fragment (docs/DESIGN.md "Grid storage: per-fragment boxes").

Fragment k's field lives on the nodes of its own box B_k: lo_k + [0, dims_k), stored at
offset_k + (i·dims_y + j)·dims_z + l of one buffer for all boxes. Every particle takes the dense path into
its own fragment's box: no owner words, claims or pool. Launches cover the buffer's capacity; an index past
the boxes has box_of = −1.

- `fragment_bounds`: each fragment's range of stencil nodes, what `FragmentBoxes.fit` sizes the boxes from.
- `box_clear`: m, p and the band mass of every field to 0.
- `box_p2g_runs`: Eq. multifield_p2g, m_i^k += Σ w_ip m_p, p_i^k += Σ w_ip m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p
  ∇w_ip, for the particles of fragment k into B_k, `run` consecutive particles a thread (a stencil that
  leaves B_k is counted as an escape and not deposited: the frame is then redone with larger boxes); with the
  latched normals also each field's band mass Σ w_ip m_p over its band particles (the contact gate). Two
  builds (`BOX_P2G`): with and without the band masses.
- `box_grid_update`: per field node v_i^k = p_i^k / m_i^k + Δt g where m_i^k > ε_m (else 0); where two or
  more fields hold mass at a node, the thread of the lowest fragment id there leads: it projects every pair
  in fragment order (the Gauss–Seidel of `contact.contact_projection`; normals and gate of
  `contact.contact_normal`: the fields' mass gradients, central differences inside each box, with
  m_a + m_b ≥ fill_mass, or the latched normal with both band masses > ε_b), then applies the boundaries to
  every field there. It only looks for other fields in the boxes that overlap its own (`over`, made per fit).
  Fields beyond the first `slots` at a node keep their own velocity (no contact) and are counted. A node of
  exactly two fields takes the same arithmetic from registers; three or more, the sweep (`sweep`); each pair
  goes through `pair_contact` (contact settings: `BoxContact`). Four builds (`GRID_UPDATES`): the contact
  statistics compiled in or out, exact or (on CUDA devices) with fast math; and the fast ones with the latched
  normals compiled in (`GRID_UPDATES_LATCHED`, the plane cut's).
- `box_g2p`: Eqs. field_g2p / field_apic / field_deformation from the particle's own box.
Twins: `reference.p2g`, `reference.grid_update`, `reference.contact_fields`, `reference.g2p` on K dense
fields (tests/test_fragment_boxes.py).
"""

from __future__ import annotations

import warp as wp

from ..clock import Clock, clock_dt, clock_time
from ..physics.boundary import Colliders, apply_boundaries
from ..physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT, contact_normal, contact_pair
from ..stencil import add_particle, atomic_add_vec4, finish_g2p, gather, normalized, stencil, stencil_sums
from ..storage import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW, MAX_SLOTS

wp.set_module_options({"enable_backward": False})

MAX_FIELDS = MAX_SLOTS  # most fields one contact leader projects at a node (sim.field_slots ≤ this)
vec_fi = wp.types.vector(length=MAX_FIELDS, dtype=wp.int32)


@wp.struct
class BoxView:
    """Every fragment's box (`fragment_boxes.FragmentBoxes.view`)."""

    lo: wp.array(dtype=wp.vec3i)  # [K_max] lowest node of box k
    dims: wp.array(dtype=wp.vec3i)  # [K_max] nodes per axis
    offset: wp.array(dtype=wp.int32)  # [K_max + 1] first buffer index of box k
    box_of: wp.array(dtype=wp.int32)  # [capacity] the box a buffer index belongs to (−1: none)
    over_start: wp.array(dtype=wp.int32)  # [K_max + 1] box k's overlapping boxes: over[over_start[k]:over_start[k+1]]
    over: wp.array(dtype=wp.int32)  # [K_max²] ascending fragment ids
    over_lo: wp.array(dtype=wp.vec3i)  # [K_max²] lo, dims and offset of the box over[o] (no dependent loads)
    over_dims: wp.array(dtype=wp.vec3i)
    over_off: wp.array(dtype=wp.int32)
    mp: wp.array(dtype=wp.vec4)  # [capacity] (momentum, mass)
    vel: wp.array(dtype=wp.vec3)  # [capacity]
    band: wp.array(dtype=float)  # [capacity] the field's band-particle mass (the latched normals' gate)
    origin: wp.vec3
    dx: float
    inv_dx: float
    shape: wp.vec3i  # the grid's nodes per axis (stencils are clamped into it, as on the dense grid)


@wp.struct
class BoxContact:
    """What the grid update's contact reads (`fragment_boxes.FragmentBoxes.update` fills it)."""

    eps_b: float  # latched normals: two fields touch where both band masses exceed this [kg]
    fill_mass: float  # mass-gradient normals: two fields touch where m_a + m_b ≥ this [kg]
    normal_mode: int  # contact.NORMAL_LATCHED or NORMAL_MASS_GRADIENT
    latched: wp.vec3  # n_Π of the first event (the mass-gradient normals' last fallback)
    centroids: wp.array(dtype=wp.vec3)  # [K] fragment centroids (normal fallback)
    restitution: float
    friction: float
    project: int  # apply the projection (FractureFields; 0: Local Multi-Field, detection only)
    stats: wp.array(dtype=float)  # [N_STATS]
    pair_stats: wp.array(dtype=float)  # [K·K·N_PAIR_STATS]
    n_fragments: int  # K (pair rows of pair_stats)


@wp.func
def index_in(lo: wp.vec3i, d: wp.vec3i, offset: int, node: wp.vec3i):
    """Buffer index of `node` in the box of lowest node lo, dims d, first index `offset`; −1 outside it."""
    r = node - lo
    if r[0] < 0 or r[1] < 0 or r[2] < 0 or r[0] >= d[0] or r[1] >= d[1] or r[2] >= d[2]:
        return -1
    return offset + (r[0] * d[1] + r[1]) * d[2] + r[2]


@wp.func
def box_index(b: BoxView, k: int, node: wp.vec3i):
    """Buffer index of `node` in box k, or −1 outside it."""
    return index_in(b.lo[k], b.dims[k], b.offset[k], node)


@wp.func
def partner_index(b: BoxView, o: int, node: wp.vec3i):
    """Buffer index of `node` in the overlapping box of entry o of the overlap lists, or −1 outside it."""
    return index_in(b.over_lo[o], b.over_dims[o], b.over_off[o], node)


@wp.func
def stencil_inside(b: BoxView, k: int, base: wp.vec3i):
    """All 27 nodes of the stencil at `base` lie in box k."""
    return box_index(b, k, base) >= 0 and box_index(b, k, base + wp.vec3i(2, 2, 2)) >= 0


@wp.kernel
def fragment_bounds(
    x: wp.array(dtype=wp.vec3),  # [N]
    fragment: wp.array(dtype=wp.int32),  # [N]
    origin: wp.vec3d,
    dx: wp.float64,
    run: int,  # consecutive particles a thread
    lo: wp.array2d(dtype=wp.int32),  # [K, 3] in: a large value; out: the lowest stencil base of fragment k
    hi: wp.array2d(dtype=wp.int32),  # [K, 3] in: a small value; out: the highest stencil base + 2
):
    """Each fragment's range of stencil nodes, base = ⌊(x − origin)/Δx − ½⌋ in float64 (as `FragmentBoxes.fit`
    had it from torch). A thread keeps the bounds of `run` consecutive particles while their fragment stays the
    same and reduces them once per change: particles sorted by cell mostly share their neighbours' fragment,
    so the few bounds of K boxes are not hit by one atomic per particle (torch's scatter_reduce, with one per
    particle, took most of the fit's time on a GPU; docs/benchmarks/history-2026-11.md)."""
    t = wp.tid()
    k = int(-1)  # noqa: UP018 (a dynamic Warp variable)
    a = wp.vec3i(0, 0, 0)
    c = wp.vec3i(0, 0, 0)
    for p in range(t * run, wp.min(t * run + run, x.shape[0])):
        kp = wp.max(fragment[p], 0)
        xp = x[p]
        base = wp.vec3i(0, 0, 0)
        for d in range(3):
            base[d] = int(wp.floor((wp.float64(xp[d]) - origin[d]) / dx - wp.float64(0.5)))
        if kp != k:
            if k >= 0:
                for d in range(3):
                    wp.atomic_min(lo, k, d, a[d])
                    wp.atomic_max(hi, k, d, c[d] + 2)
            k = kp
            a = base
            c = base
        else:
            for d in range(3):
                a[d] = wp.min(a[d], base[d])
                c[d] = wp.max(c[d], base[d])
    if k >= 0:
        for d in range(3):
            wp.atomic_min(lo, k, d, a[d])
            wp.atomic_max(hi, k, d, c[d] + 2)


@wp.kernel
def box_clear(b: BoxView):
    t = wp.tid()
    b.mp[t] = wp.vec4(0.0)
    b.band[t] = 0.0


@wp.func
def flush_box(b: BoxView, origin: int, d: wp.vec3i, acc: stencil_sums):
    """Add a run's 27 node sums to its box (stencil origin at buffer index `origin`, box dims d): one reduction
    per node."""
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                q = 9 * i + 3 * j + l
                atomic_add_vec4(
                    b.mp, origin + (i * d[1] + j) * d[2] + l, wp.vec4(acc[q, 0], acc[q, 1], acc[q, 2], acc[q, 3])
                )


def _box_p2g(band: bool) -> wp.Kernel:
    """`box_p2g_runs` with the band masses of the latched normals' gate compiled in (`band`) or out. Out, no
    atomic on the band buffer stands between one particle's loads and the next's (the compiler must assume it may
    write what they read), and the kernel is smaller."""
    BAND = int(band)  # noqa: N806 (a compile-time constant of the kernel, read by wp.static)

    def box_p2g_runs(
        x: wp.array(dtype=wp.vec3),  # [N]
        v: wp.array(dtype=wp.vec3),  # [N]
        C: wp.array(dtype=wp.mat33),  # [N]
        mass: wp.array(dtype=float),  # [N]
        volume: wp.array(dtype=float),  # [N] rest volume V⁰
        stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ
        fragment: wp.array(dtype=wp.int32),  # [N] the particle's box
        clock: Clock,  # Δt
        b: BoxView,
        run: int,  # consecutive particles per thread
        counts: wp.array(dtype=wp.int32),  # [N_COUNTS]
        band: wp.array(dtype=wp.int32),  # [N] γ_p ≠ 0: an interface-band particle (read by the band build only)
    ):
        """Deposits of `run` consecutive particles a thread (`grid.run_kernels.p2g_runs` on boxes): those with the
        same fragment and stencil base are summed in registers and reach their box as one reduction per node
        (run = 1: one particle a thread). The box's bounds are loaded when the fragment changes and the stencil
        is checked against its box when the run changes, not per particle (per particle, the check was a
        measurable share of the kernel at K = 16). The band build also adds the band particles' w_ip m_p to their
        field's band mass."""
        t = wp.tid()
        dt = clock_dt(clock)
        acc = stencil_sums()
        cur = wp.vec3i(-1, -1, -1)
        ck = int(-1)  # noqa: UP018 (a dynamic Warp variable)
        bk = int(-1)  # noqa: UP018 (the fragment whose box bounds are loaded)
        blo = wp.vec3i(0, 0, 0)
        bd = wp.vec3i(0, 0, 0)
        boff = int(0)  # noqa: UP018
        start = int(-1)  # noqa: UP018 (buffer index of the current run's stencil origin; −1: it left its box)
        rd = wp.vec3i(0, 0, 0)  # and its box's dims
        for p in range(t * run, wp.min(t * run + run, x.shape[0])):
            k = wp.max(fragment[p], 0)
            if k != bk:
                blo = b.lo[k]
                bd = b.dims[k]
                boff = b.offset[k]
                bk = k
            base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
            if k != ck or base[0] != cur[0] or base[1] != cur[1] or base[2] != cur[2]:
                # a new run: flush the last one, and check once whether this stencil lies in its box
                if start >= 0:
                    flush_box(b, start, rd, acc)
                acc = stencil_sums()
                cur = base
                ck = k
                start = index_in(blo, bd, boff, base)
                if index_in(blo, bd, boff, base + wp.vec3i(2, 2, 2)) < 0:
                    start = -1
                rd = bd
            if start < 0:
                wp.atomic_add(counts, COUNT_ESCAPED, 1)  # the stencil left its box: the frame is redone
                continue
            m = mass[p]
            if wp.static(BAND):
                if band[p] != 0:
                    for i in range(3):
                        for j in range(3):
                            for l in range(3):  # noqa: E741
                                q = start + (i * rd[1] + j) * rd[2] + l
                                wp.atomic_add(b.band, q, w[i, 0] * w[j, 1] * w[l, 2] * m)
            force = -dt * volume[p] * stress[p]
            acc = add_particle(acc, f, w, dw, b.dx, b.inv_dx, m, v[p], C[p], force)
        if start >= 0:
            flush_box(b, start, rd, acc)

    return wp.kernel(box_p2g_runs, name="box_p2g_runs" + ("_band" if band else ""))


BOX_P2G = {band: _box_p2g(band) for band in (False, True)}
"""The box P2G by (add the band masses)."""


@wp.func
def node_mass(b: BoxView, i: int, step: int, r: int, extent: int):
    """Mass at buffer index i + step, whose coordinate along its axis is r (0 outside [0, extent))."""
    if r < 0 or r >= extent:
        return 0.0
    return b.mp[i + step][3]


@wp.func
def box_mass_gradient(b: BoxView, k: int, i: int, node: wp.vec3i):
    """∇m^k at the node of buffer index i in box k, by central differences of the box's nodal masses (0 beyond
    the box) [kg/m]."""
    d = b.dims[k]
    r = node - b.lo[k]
    sx = d[1] * d[2]
    h = 0.5 * b.inv_dx
    gx = node_mass(b, i, sx, r[0] + 1, d[0]) - node_mass(b, i, -sx, r[0] - 1, d[0])
    gy = node_mass(b, i, d[2], r[1] + 1, d[1]) - node_mass(b, i, -d[2], r[1] - 1, d[1])
    gz = node_mass(b, i, 1, r[2] + 1, d[2]) - node_mass(b, i, -1, r[2] - 1, d[2])
    return wp.vec3(gx, gy, gz) * h


@wp.func
def four_partners(b: BoxView, o: int, end: int, node: wp.vec3i, t: int):
    """Buffer indices at `node` of the overlap entries o … o + 3 (−1: the node lies outside that box, or the
    entry is past `end`) and their masses, the four loads issued together (a −1 reads node t's own mass,
    unused)."""
    ii = wp.vec4i(-1, -1, -1, -1)
    for a in range(4):
        if o + a < end:
            ii[a] = partner_index(b, o + a, node)
    mm = wp.vec4(0.0)
    for a in range(4):
        mm[a] = b.mp[wp.where(ii[a] >= 0, ii[a], t)][3]
    return ii, mm


@wp.func
def box_node(b: BoxView, k: int, t: int):
    """The grid node of buffer index t in box k."""
    d = b.dims[k]
    r = t - b.offset[k]
    return b.lo[k] + wp.vec3i(r // (d[1] * d[2]), (r // d[2]) % d[1], r % d[2])


@wp.func
def meeting_fields(
    b: BoxView,
    t: int,
    k: int,
    node: wp.vec3i,
    xi: wp.vec3,
    slots: int,
    eps_m: float,
    dt: float,
    gravity: wp.vec3,
    time: float,
    colliders: Colliders,
    counts: wp.array(dtype=wp.int32),
):
    """The other fields with mass at the node of buffer index t in box k, from the boxes that overlap box k
    (ascending: lower fragments first): (n, their buffer indices, their fragments), n = −1 where a lower
    fragment has mass here (its thread leads). Fields beyond the first `slots` keep their own velocity and the
    boundaries (written here) and are counted as slot overflows."""
    idx = vec_fi(-1)
    frag = vec_fi(-1)
    n = int(0)  # noqa: UP018 (a dynamic Warp variable)
    o = b.over_start[k]
    end = b.over_start[k + 1]
    while o < end:  # four entries' masses loaded at once: the walk waits on memory once per four
        ii, mm = four_partners(b, o, end, node, t)
        for e in range(4):
            i = ii[e]
            if i >= 0 and mm[e] > eps_m:
                j = b.over[o + e]
                if j < k:
                    return -1, idx, frag
                if n + 1 < slots:
                    idx[n] = i
                    frag[n] = j
                    n += 1
                else:  # kept, uncoupled
                    wp.atomic_add(counts, COUNT_SLOT_OVERFLOW, 1)
                    b.vel[i] = apply_boundaries(normalized(b.mp[i], eps_m, dt, gravity), node, xi, time, colliders)
        o += 4
    return n, idx, frag


@wp.func
def sweep(
    b: BoxView,
    c: BoxContact,
    record: int,
    mode: int,
    t: int,
    k: int,
    q: wp.vec4,
    node: wp.vec3i,
    xi: wp.vec3,
    n: int,
    idx: vec_fi,
    frag: vec_fi,
    eps_m: float,
    dt: float,
    gravity: wp.vec3,
    time: float,
    colliders: Colliders,
):
    """A node of n + 1 fields led by buffer index t (fragment k, (p, m) q), the others at idx[:n] of fragments
    frag[:n]: every field normalized, every pair projected in fragment order (Gauss–Seidel), then each field's
    boundaries."""
    b.vel[t] = normalized(q, eps_m, dt, gravity)
    for a in range(n):
        b.vel[idx[a]] = normalized(b.mp[idx[a]], eps_m, dt, gravity)
    for a in range(n + 1):  # field 0 is the leader's own, then the partners in fragment order
        ia = t
        ka = k
        if a > 0:
            ia = idx[a - 1]
            ka = frag[a - 1]
        ma = b.mp[ia][3]
        va = b.vel[ia]  # final after the pairs with lower fields; kept in registers through its own pairs
        for e in range(a, n):
            ie = idx[e]
            va, w1 = pair_contact(b, c, record, mode, ia, ie, ka, frag[e], va, b.vel[ie], ma, b.mp[ie][3], node, time)
            b.vel[ie] = w1
        b.vel[ia] = apply_boundaries(va, node, xi, time, colliders)


@wp.func
def pair_contact(
    b: BoxView,
    c: BoxContact,
    record: int,
    mode: int,
    i0: int,
    i1: int,
    k0: int,
    k1: int,
    v0: wp.vec3,
    v1: wp.vec3,
    m0: float,
    m1: float,
    node: wp.vec3i,
    time: float,
):
    """Fields i0, i1 (fragments k0 < k1, velocities v0, v1, masses m0, m1) at `node` after their contact: the
    gate (both band masses > ε_b with the latched normal, m0 + m1 ≥ fill_mass with mass gradients), the
    normal, then `contact.contact_pair` (projection and statistics)."""
    nrm = c.latched
    if mode == NORMAL_MASS_GRADIENT:
        if not (m0 + m1 >= c.fill_mass):
            return v0, v1
        g0 = box_mass_gradient(b, k0, i0, node)
        g1 = box_mass_gradient(b, k1, i1, node)
        nrm = contact_normal(mode, c.latched, g0, g1, c.centroids, k0, k1)
    elif not (b.band[i0] > c.eps_b and b.band[i1] > c.eps_b):
        return v0, v1
    return contact_pair(
        v0, v1, m0, m1, nrm, c.restitution, c.friction, c.project, record, c.stats, c.pair_stats, k0, k1,
        c.n_fragments, time,
    )  # fmt: skip


def _grid_update(record: bool, fast: bool, mode: int = -1) -> wp.Kernel:
    """`box_grid_update` with the contact statistics compiled in (`record`) or out, exact or with fast math
    (`fast`), the normals' mode (`contact.NORMAL_*`) compiled in or (−1) read from the contact settings. Out
    (timing runs, `Simulator.record_contact = False`), no atomic stands between the leaders' loads (the compiler
    must assume an atomic may write what a later load reads; the fast-math builds take 64 registers either way on
    sm_90): the quiet build made K = 16 faster and the plane cut's grid update a little slower, both within
    their targets (docs/benchmarks/history-2026-11.md, ninth session). Fast math shortens the leaders' chains of
    dependent arithmetic (approximate division and square root: a sixth off the K = 16 grid update, velocities
    within 2e-7 relative; seventh session); the CPU keeps the exact
    kernels (Warp would build a fast-math kernel with fast math on the CPU too), so the CPU's bitwise equalities
    with the slot storage hold."""
    RECORD = int(record)  # noqa: N806 (a compile-time constant of the kernel, read by wp.static)
    MODE = int(mode)  # noqa: N806 (the normals' mode compiled in; −1: read from the contact settings)

    def box_grid_update(
        b: BoxView,
        c: BoxContact,
        eps_m: float,
        slots: int,  # fields a leader projects (≤ MAX_FIELDS); more are counted as slot overflows
        clock: Clock,  # Δt and t
        gravity: wp.vec3,
        colliders: Colliders,
        counts: wp.array(dtype=wp.int32),
    ):
        """One thread per buffer index: normalization and boundaries of its field, or, where fields meet, the
        lowest fragment's thread does the whole node (normalization, contact, boundaries) and the others skip it."""
        t = wp.tid()
        k = b.box_of[t]
        q = b.mp[t]  # loaded beside the box id, not after it: an index past the boxes holds m = 0
        if k < 0 or q[3] <= eps_m:
            if k >= 0 and q[3] > 0.0:  # a node no particle reached (m = 0) is read by no G2P: no write
                b.vel[t] = wp.vec3(0.0)
            return
        dt = clock_dt(clock)
        time = clock_time(clock)
        node = box_node(b, k, t)
        xi = b.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * b.dx
        n, idx, frag = meeting_fields(b, t, k, node, xi, slots, eps_m, dt, gravity, time, colliders, counts)
        mode = c.normal_mode
        if wp.static(MODE >= 0):
            mode = wp.static(MODE)
        if n < 0:
            return  # a lower fragment has mass here: its thread leads
        if n == 0:
            b.vel[t] = apply_boundaries(normalized(q, eps_m, dt, gravity), node, xi, time, colliders)
            return
        if n > 1:
            sweep(b, c, wp.static(RECORD), mode, t, k, q, node, xi, n, idx, frag, eps_m, dt, gravity, time, colliders)
            return
        # two fields, the most common meeting: the sweep's one pair from values loaded once, both boundaries
        # applied before either velocity is stored (the sweep's stores and reloads were the critical path here:
        # the K = 2 grid update a quarter shorter without them; docs/benchmarks/history-2026-11.md, eighth session)
        i1 = idx[0]
        q1 = b.mp[i1]
        v0 = normalized(q, eps_m, dt, gravity)
        v1 = normalized(q1, eps_m, dt, gravity)
        w0, w1 = pair_contact(b, c, wp.static(RECORD), mode, t, i1, k, frag[0], v0, v1, q[3], q1[3], node, time)
        w0 = apply_boundaries(w0, node, xi, time, colliders)
        w1 = apply_boundaries(w1, node, xi, time, colliders)
        b.vel[t] = w0
        b.vel[i1] = w1

    name = "box_grid_update" + ("_fast" if fast else "") + ("" if record else "_quiet")
    name += "" if mode < 0 else f"_n{mode}"
    if not fast:  # the exact kernels build with the rest of this module
        return wp.kernel(box_grid_update, name=name)
    return wp.kernel(
        box_grid_update, name=name, module="unique", module_options={"fast_math": True, "enable_backward": False}
    )


GRID_UPDATES = {(record, fast): _grid_update(record, fast) for record in (True, False) for fast in (False, True)}
"""The grid update by (record the contact statistics, fast math), reading the normals' mode."""
GRID_UPDATES_LATCHED = {record: _grid_update(record, True, NORMAL_LATCHED) for record in (True, False)}
"""The fast-math grid update with the latched normals compiled in, by (record): the plane cut's grid update gets
shorter. The mass-gradient normals keep the build that reads the mode: compiled in, K = 16's got slower
(docs/benchmarks/history-2026-11.md, tenth session)."""


def grid_update_kernel(record: bool, fast: bool, mode: int) -> wp.Kernel:
    """The build of the grid update a launch takes: statistics compiled in only where they are kept, fast math
    (CUDA) with the latched normals compiled in for the plane cut, the mode-reading build otherwise."""
    if fast and mode == NORMAL_LATCHED:
        return GRID_UPDATES_LATCHED[record]
    return GRID_UPDATES[record, fast]


@wp.kernel
def box_g2p(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    fragment: wp.array(dtype=wp.int32),
    clock: Clock,  # Δt
    b: BoxView,
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
):
    p = wp.tid()
    k = wp.max(fragment[p], 0)
    base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
    if not stencil_inside(b, k, base):
        return  # counted by P2G
    vp, B, gradv = gather(b.vel, b.offset[k], b.dims[k], base - b.lo[k], f, w, dw, b.dx, b.inv_dx)
    finish_g2p(p, vp, B, gradv, clock_dt(clock), b.inv_dx, x, v, C, F, lower, upper, counts)
