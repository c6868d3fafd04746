"""The slot storage's grid update (`sim.grid.kernels.grid_update_dense` and `grid_update_pool`) on fields written
by hand, against hand values:

- the dense pass gives every node v = p/m + Δt g where m > ε_m (else 0) — except, on a multi-field grid, the
  nodes with a pool row, which it leaves whole to the pool pass (their slot 0 too);
- the pool pass orders each pair by fragment id, whatever slot holds which: the normal points from the lower id
  into the higher, so approaching and separating are judged the same way in either arrangement;
- with mass-gradient normals two fields touch where together they fill the node, m_a + m_b ≥ fill mass (equality
  included);
- a field holding exactly ε_m is inactive: it is in no contact and no collider acts on it (it stays 0).

A 5³ grid with two slots; Δt = 2⁻¹⁰ s and g = −1024 m/s² on z where used, so Δt g = −1 m/s exactly."""

import torch
import warp as wp
from simutil import fill_slots

from fracture_gs.config import CuboidBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import grid_update_dense, grid_update_pool
from fracture_gs.sim.grid.layout import ROW_FLAG
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT

ensure_warp()
S, DT, EPS = 5, 2.0**-10, 0.25


def _clock():
    c = FrameClock("cpu", 0)
    c.set(DT, [0.0])
    return c


def test_the_dense_pass_leaves_nodes_with_a_row_to_the_pool_pass():
    """Slot 0 holds m = 1, p = (1, 0, 0) at every node, velocities preset to 7; nodes i = 0 carry a row flag and
    node (3, 3, 3) holds exactly ε_m. Multi-field: i = 0 keeps 7, (3, 3, 3) gets 0, the rest (1, 0, −1). One field:
    the row flags mean nothing, i = 0 gets (1, 0, −1) too."""
    for multi in (1, 0):
        g = Grid((0.0, 0.0, 0.0), 0.2, (S, S, S), "cpu", slots=2)
        g.mp[:] = torch.tensor([1.0, 0.0, 0.0, 1.0])
        g.mp[3, 3, 3] = torch.tensor([EPS, 0.0, 0.0, EPS])
        g.vel.fill_(7.0)
        owner = g._owner.view(S, S, S)
        owner[:] = 1
        owner[0] |= ROW_FLAG
        colliders = Boundaries([], "cpu", (S, S, S), 0).colliders
        inputs = [g.view, wp.vec3i(0, 0, 0), multi, EPS, _clock().view, wp.vec3(0.0, 0.0, -1024.0), colliders]
        wp.launch(grid_update_dense, (S, S, S), inputs, device="cpu")
        want = torch.tensor([1.0, 0.0, -1.0]).expand(S, S, S, 3).clone()
        want[3, 3, 3] = 0.0
        if multi:
            want[0] = 7.0
        assert torch.equal(g.vel, want), multi


def _pool(m, v, owners=None, mode=NORMAL_LATCHED, fill_mass=0.0, gate=1, bounds=()):
    """Two fields (m [2, X, Y, Z], v [2, X, Y, Z, 3]) in slot 0 and the pool slot, band mass 0.5 each; `owners`
    [X, Y, Z] bool: there fragment 1 holds slot 0 and fragment 0 the pool slot (their fields swapped with them).
    One pool pass, e = 0, μ = 0, no gravity, latched normal +z, centroids 0 → +z. Returns the fields' velocities
    [2, X, Y, Z, 3] by fragment."""
    g = Grid((0.0, 0.0, 0.0), 0.2, (S, S, S), "cpu", slots=2)
    g.ensure_pool(S**3)
    fill_slots(g, m, v, torch.full_like(m, 0.5))
    if owners is not None:
        o = owners.reshape(-1)
        g._owner[o] = (g._owner[o] & ~0xFFFF) | 2
        rows = torch.nonzero(torch.isin(g.key, torch.nonzero(o).flatten().int())).flatten()
        g.pool_owner[rows] = 0
        n = g.n_nodes
        idx = torch.nonzero(o).flatten()
        r_of = {int(g.key[r]): int(r) for r in rows}
        pool = torch.tensor([n + r_of[int(i)] for i in idx])
        a, b = g._mp[idx].clone(), g._mp[pool].clone()
        g._mp[idx], g._mp[pool] = b, a
    cen = wp.from_torch(torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), dtype=wp.vec3)
    grad0 = wp.zeros(g.capacity, dtype=wp.vec3, device="cpu")
    colliders = Boundaries(list(bounds), "cpu", (S, S, S), 0).colliders
    inputs = [g.view, EPS, 0.25, float(fill_mass), gate, 1, mode, wp.vec3(0.0, 0.0, 1.0), cen, 0.0, 0.0]
    inputs += [_clock().view, wp.vec3(0.0, 0.0, 0.0), colliders, 0, g.wp["stats"], g.wp["pair_stats"], 2, grad0]
    wp.launch(grid_update_pool, dim=g.capacity, inputs=inputs, device="cpu")
    vel = g._vel.clone()
    out = torch.zeros(2, S**3, 3)
    f0 = (g._owner.long() & 0xFFFF) - 1
    for node in range(S**3):
        r = int(torch.nonzero(g.key == node).flatten()[0])
        k0 = int(f0[node])
        out[k0, node] = vel[node]
        out[1 - k0, node] = vel[g.n_nodes + r]
    return out.view(2, S, S, S, 3)


def _fields(v0, v1, m0=1.0, m1=1.0):
    m = torch.stack([torch.full((S, S, S), m0, dtype=torch.float64), torch.full((S, S, S), m1, dtype=torch.float64)])
    v = torch.tensor([v0, v1], dtype=torch.float64)[:, None, None, None, :].expand(2, S, S, S, 3).clone()
    return m, v


def test_each_pair_is_ordered_by_fragment_id_whatever_slot_holds_it():
    """Fragment 0 moving +z at 1 m/s and fragment 1 at −1 m/s approach along the normal 0 → 1 (+z): both stop
    (equal masses, e = 0), in the nodes where fragment 0 holds slot 0 and in those (i ≤ 1) where fragment 1 does.
    Reversed velocities separate: untouched, in both arrangements."""
    swapped = torch.zeros(S, S, S, dtype=torch.bool)
    swapped[:2] = True
    for v0, v1, stop in (((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), True), ((0.0, 0.0, -1.0), (0.0, 0.0, 1.0), False)):
        m, v = _fields(v0, v1)
        got = _pool(m, v, swapped)
        want = torch.zeros_like(got) if stop else v.float()
        assert torch.equal(got, want), (v0, v1)


def test_mass_gradient_fields_touch_where_they_fill_the_node_equality_included():
    """Mass-gradient normals (no gradients: centroids 0 → 1, +z), approaching at ±1 m/s, masses 1 and 1: with a
    fill mass of 2 they touch (both stop); with the next float above 2 they do not (untouched)."""
    m, v = _fields((0.0, 0.0, 1.0), (0.0, 0.0, -1.0))
    assert torch.equal(_pool(m, v, mode=NORMAL_MASS_GRADIENT, fill_mass=2.0), torch.zeros(2, S, S, S, 3))
    above = float(torch.nextafter(torch.tensor(2.0), torch.tensor(3.0)))
    assert torch.equal(_pool(m, v, mode=NORMAL_MASS_GRADIENT, fill_mass=above), v.float())


def test_a_field_holding_exactly_eps_m_is_in_no_contact_and_under_no_collider():
    """Fragment 0 holds exactly ε_m: its velocity is 0 and fragment 1 (m = 1, −1 m/s toward it) is not stopped by
    it. Inside a sticky box moving at (0.5, 0, 0), without contact, the active field takes the box's velocity and
    the field at ε_m stays 0."""
    m, v = _fields((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), m0=EPS)
    got = _pool(m, v)
    assert torch.equal(got[0], torch.zeros(S, S, S, 3))
    assert torch.equal(got[1], v[1].float())
    box = CuboidBoundary(lower=(-1.0, -1.0, -1.0), upper=(2.0, 2.0, 2.0), velocity=(0.5, 0.0, 0.0))
    got = _pool(m, v, gate=0, bounds=[box])
    assert torch.equal(got[0], torch.zeros(S, S, S, 3))
    assert torch.equal(got[1], torch.tensor([0.5, 0.0, 0.0]).expand(S, S, S, 3))
