"""Small particle scenes for solver tests (a few thousand particles, coarse grids)."""

import torch

from fracture_gs import sim as S
from fracture_gs.io.gaussian_set import quat_to_matrix


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
    from fracture_gs.sim.layout import ROW_FLAG

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
