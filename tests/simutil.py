"""Small particle scenes for solver tests (a few thousand particles, coarse grids)."""

import torch
import warp as wp

from fracture_gs import sim as S
from fracture_gs.io.gaussian_set import quat_to_matrix
from fracture_gs.sim.boxes.kernels import BoxView, box_mass_gradient
from fracture_gs.sim.physics.boundary import Boundaries, Colliders, apply_boundaries


def block(lo, hi, spacing, jitter=0.0, generator=None):
    """Particles on a (jittered) lattice filling the box [lo, hi]; returns x [N,3] and volume per particle."""
    axes = [torch.arange(a + spacing / 2, b, spacing, dtype=torch.float64) for a, b in zip(lo, hi)]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    if jitter:
        x = x + (torch.rand(x.shape, generator=generator, dtype=torch.float64) - 0.5) * jitter * spacing
    return x.float(), spacing**3


def particles(x, vol, rho=1000.0, **kw):
    n = x.shape[0]
    return S.Particles(x=x, mass=torch.full((n,), rho * vol), volume=torch.full((n,), vol), **kw)


def config(n=32, **kw):
    kw.setdefault("gravity", (0.0, 0.0, 0.0))
    return S.SimConfig(dx=1.0 / n, grid_shape=(n, n, n), grid_origin=(0.0, 0.0, 0.0), **kw)


def rand_rotations(n, generator=None):
    return quat_to_matrix(torch.randn(n, 4, generator=generator, dtype=torch.float64))


def rel_err(a, b):
    a, b = a.double().cpu(), b.double().cpu()
    return float((a - b).norm() / b.norm().clamp_min(1e-300))


def angular_momentum(P, dx):
    """APIC angular momentum Σ m (x × v + Δx²/4 · axial(C)) (exactly what P2G puts on the grid)."""
    x, v, C, m = P.x.double(), P.v.double(), P.C.double(), P.mass.double()
    ax = torch.stack([C[:, 2, 1] - C[:, 1, 2], C[:, 0, 2] - C[:, 2, 0], C[:, 1, 0] - C[:, 0, 1]], 1)
    return (m[:, None] * (torch.cross(x, v, dim=1) + dx * dx / 4 * ax)).sum(0)


def skew(w):
    return torch.tensor([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def fill_slots(grid, m, v, band=None):
    """Write K fields straight into a multi-field grid's slot storage: at every node fragment 0 in
    slot 0 and fragments 1 … K−1 in pool slots 1 … K−1 of the node's row, inserted at its hash
    position like P2G would (so neighbour lookups find it). m [K, X, Y, Z], v [K, X, Y, Z, 3], band
    [K, …] (default: m); velocities are stored as (p, m) like P2G leaves them."""
    from fracture_gs.sim.grid.layout import ROW_FLAG

    K = m.shape[0]
    n = grid.n_nodes
    assert K <= grid.slots and grid.capacity >= 2 * n, "grid too small for the fields"
    band = m if band is None else band
    dev = grid.device
    grid.clear()
    p = (m[..., None] * v).reshape(K, n, 3).to(dev, torch.float32)
    mm = m.reshape(K, n).to(dev, torch.float32)
    grid._mp[:n] = torch.cat([p[0], mm[0, :, None]], 1)
    grid._owner[:] = 1 | ROW_FLAG
    mask, key = grid.capacity - 1, [-1] * grid.capacity
    rows = []
    for node in range(n):  # linear probing from layout.row_hash
        h = ((node * 1640531527) & 0x7FFFFFFF) & mask
        while key[h] != -1:
            h = (h + 1) & mask
        key[h] = node
        rows.append(h)
    grid.key.copy_(torch.tensor(key, dtype=torch.int32))
    rows = torch.tensor(rows, device=dev)
    s1 = grid.slots - 1
    for k in range(1, K):
        idx = n + rows * s1 + (k - 1)
        grid._mp[idx] = torch.cat([p[k], mm[k, :, None]], 1)
        grid.pool_owner[rows * s1 + (k - 1)] = k
    b = band.reshape(K, n).to(dev, torch.float32)
    grid.band.view(grid.capacity, grid.slots)[rows, :K] = b.T
    grid.n_fields = K


def field_masses(sim):
    """Mass of every node field [K, X, Y, Z] the solver's transfer deposits for the particles where they are now:
    the per-fragment boxes' fields (boxed storage), else a fresh P2G of the current state into a scratch grid
    routed as the solver routes (by fragment after a latch of a multi-field variant, all into one field
    otherwise). Reads the code under test's deposits; `foreign_mass` judges them by hand."""
    import warp as wp

    from fracture_gs.sim.grid.fields import Grid
    from fracture_gs.sim.storage import N_COUNTS

    if sim.boxed:
        return sim.box_fields()[0].double().cpu()
    g, multi = sim.grid, sim.multifield
    scratch = Grid(g.origin, g.dx, g.shape, sim.device, slots=sim.cfg.field_slots if multi else 1, max_fragments=64)
    scratch.n_fields = sim.n_fragments if multi else 1
    if multi:
        scratch.ensure_pool(g.n_nodes)
    counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=sim.device)
    sim.p2g(sim.dt, target=scratch, multifield=multi, counts=wp.from_torch(counts))
    return scratch.mass.double().cpu()


def foreign_mass(sim, mass):
    """Realized mixing checked by hand: each particle of fragment k reads its velocity from one node field at
    each of its 27 stencil nodes (field k under a fragment-conditioned transfer, the one shared field otherwise).
    From the particles' positions, masses and fragment ids alone this computes, with the quadratic B-spline
    written out, the mass fragment k itself puts at every node, own[k, n] = Σ_{p ∈ k} m_p w_pn; then
    foreign = Σ_k Σ_{n reached by k} (mass[field read by k, n] − own[k, n]): the mass other fragments deposited
    into the fields fragment k reads; and shared = Σ_k Σ_{n reached by k} Σ_{j ≠ k} own[j, n], what they would
    deposit into a field common to all. Returns (foreign, shared, total particle mass) in kg."""
    import numpy as np

    P, g = sim.particles, sim.grid
    x = P.x.double().cpu().numpy()
    m = P.mass.double().cpu().numpy()
    frag = P.fragment.cpu().numpy().astype(np.int64)
    K = int(frag.max()) + 1
    shape = tuple(g.shape)
    xi = (x - np.asarray(g.origin)) / g.dx
    base = np.floor(xi - 0.5).astype(np.int64)
    f = xi - base
    w = np.stack([0.5 * (1.5 - f) ** 2, 0.75 - (f - 1.0) ** 2, 0.5 * (f - 0.5) ** 2], 1)  # [N, 3 (offset), 3 (axis)]
    own = np.zeros((K, int(np.prod(shape))))
    for a in range(3):
        for b in range(3):
            for c in range(3):
                node = np.ravel_multi_index((base[:, 0] + a, base[:, 1] + b, base[:, 2] + c), shape)
                np.add.at(own, (frag, node), m * w[:, a, 0] * w[:, b, 1] * w[:, c, 2])
    fields = mass.numpy().reshape(mass.shape[0], -1)
    foreign = shared = 0.0
    for k in range(K):
        reach = own[k] > 0
        read = fields[k if fields.shape[0] > 1 else 0]
        foreign += float((read[reach] - own[k][reach]).sum())
        shared += float(np.delete(own, k, axis=0)[:, reach].sum())
    return foreign, shared, float(m.sum())


def zero_padded_gradient(m, inv_dx):
    """Central differences (m[i+1] − m[i−1]) · ½/Δx of a box's node masses m [X, Y, Z], with zero mass beyond every
    face: the mass gradient a box's kernel must give. Returns [X·Y·Z, 3] in the box's flat node order."""
    pad = torch.nn.functional.pad(m, (1, 1, 1, 1, 1, 1))
    return torch.stack(
        [
            pad[2:, 1:-1, 1:-1] - pad[:-2, 1:-1, 1:-1],
            pad[1:-1, 2:, 1:-1] - pad[1:-1, :-2, 1:-1],
            pad[1:-1, 1:-1, 2:] - pad[1:-1, 1:-1, :-2],
        ],
        -1,
    ).reshape(-1, 3) * (0.5 * inv_dx)


@wp.kernel
def _box_gradients(b: BoxView, k: int, out: wp.array(dtype=wp.vec3)):
    t = wp.tid()
    d = b.dims[k]
    node = b.lo[k] + wp.vec3i(t // (d[1] * d[2]), (t // d[2]) % d[1], t % d[2])
    out[t] = box_mass_gradient(b, k, b.offset[k] + t, node)


def box_gradient(boxes, k):
    """`box_mass_gradient` at every node of box k of `boxes` (a FragmentBoxes on the CPU): [nodes, 3] float64 in
    the box's flat node order, to hold against `zero_padded_gradient`."""
    d = [int(v) for v in boxes.dims[k]]
    out = wp.zeros(d[0] * d[1] * d[2], dtype=wp.vec3, device="cpu")
    wp.launch(_box_gradients, dim=out.shape[0], inputs=[boxes.view, k, out], device="cpu")
    return wp.to_torch(out).double()


@wp.kernel
def _boundaries_at(
    v: wp.array(dtype=wp.vec3),  # [M]
    x: wp.array(dtype=wp.vec3),  # [M]
    t: float,
    c: Colliders,
    out: wp.array(dtype=wp.vec3),  # [M]
):
    i = wp.tid()
    out[i] = apply_boundaries(v[i], wp.vec3i(8, 8, 8), x[i], t, c)


def boundaries_applied(items, v, x, t, shape=(64, 64, 64)) -> torch.Tensor:  # [M, 3] float64
    """`apply_boundaries` (the grid update's operator) on nodes at x [M, 3] with velocities v [M, 3] at time t, for
    the boundary `items` of a grid of `shape` without domain walls."""
    b = Boundaries(items, "cpu", shape, 0)
    out = wp.zeros(len(v), dtype=wp.vec3, device="cpu")
    vw = wp.from_torch(torch.tensor(v, dtype=torch.float32).contiguous(), dtype=wp.vec3)
    xw = wp.from_torch(torch.tensor(x, dtype=torch.float32).contiguous(), dtype=wp.vec3)
    wp.launch(_boundaries_at, dim=len(v), inputs=[vw, xw, float(t), b.colliders], outputs=[out], device="cpu")
    return wp.to_torch(out).double()
