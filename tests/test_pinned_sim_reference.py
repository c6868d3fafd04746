"""`sim/reference.py`, the float64 law the kernels are checked against: its stencil against the quadratic
B-spline's reproduction identities, its grid update and its pairwise contact (`contact_fields`) against
hand-derived two-body impulses: two fields at one node with masses 1 and 3 approach
along n = +z at 1 m/s while sliding 0.5 m/s in x, both carried by a common velocity W (the law is
Galilean invariant: the hand-derived answers for W = 0 shift by W). With restitution e = 0.5 the normal impulse is
J = (1 + e)·1 / (1/1 + 1/3) = 1.125; the tangential one is min(s / (1/m₀ + 1/m₁), μJ) = min(0.375, μJ)."""

import torch

from fracture_gs.sim.reference import contact, contact_fields, grid_update, stencil

N = torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64)
W = torch.tensor([0.25, -0.125, 0.5], dtype=torch.float64)


def _pair(mu, e=0.5, swap=False, band=(1.0, 1.0)):
    """Contact of fragment 0 (mass 1, v = W) and fragment 1 (mass 3, v = W + (0.5, 0, −1)); returns their
    velocities after, less W, as (v of fragment 0, v of fragment 1)."""
    v = torch.tensor([[[0.0, 0.0, 0.0], [0.5, 0.0, -1.0]]], dtype=torch.float64) + W
    m = torch.tensor([[1.0, 3.0]], dtype=torch.float64)
    frag = torch.tensor([[0, 1]])
    b = torch.tensor([band], dtype=torch.float64)
    if swap:  # fragment 1 in slot 0: the law orients the pair by fragment id, not by slot
        v, m, frag, b = v.flip(1), m.flip(1), frag.flip(1), b.flip(1)
    out = contact_fields(v, m, frag, b, 1e-9, 0.5, lambda a, bb, lo, hi: N, e=e, mu=mu)[0]
    out = out - W
    return (out[1], out[0]) if swap else (out[0], out[1])


def test_contact_restitutes_the_normal_velocity_and_sticks_under_high_friction():
    """μ = 10: the normal relative velocity reverses to e·1 = 0.5 m/s, the tangential slip stops (the
    tangential impulse 0.375 < μJ), and momentum is conserved: v₀ = (0.375, 0, −1.125), v₁ = (0.375, 0, −0.625)."""
    v0, v1 = _pair(mu=10.0)
    assert torch.allclose(v0, torch.tensor([0.375, 0.0, -1.125], dtype=torch.float64), atol=1e-12)
    assert torch.allclose(v1, torch.tensor([0.375, 0.0, -0.625], dtype=torch.float64), atol=1e-12)
    assert torch.allclose(1 * v0 + 3 * v1, torch.tensor([1.5, 0.0, -3.0], dtype=torch.float64), atol=1e-12)


def test_contact_friction_is_capped_at_mu_times_the_normal_impulse():
    """μ = 0.1: the tangential impulse is μJ = 0.1125, so the slip drops from 0.5 by 0.1125·(1 + 1/3) = 0.15
    to 0.35 m/s; the normal part is as without friction."""
    v0, v1 = _pair(mu=0.1)
    slip = float(v1[0] - v0[0])
    assert abs(slip - 0.35) < 1e-12
    assert abs(float(v1[2] - v0[2]) - 0.5) < 1e-12
    w0, w1 = _pair(mu=0.0)
    assert float(w1[0] - w0[0]) == 0.5 and abs(float(w0[2]) - v0[2]) < 1e-12


def test_contact_is_oriented_by_fragment_id_not_by_slot():
    """The same pair stored with fragment 1 in the first slot gets the same velocities (the normal points
    from the lower fragment id into the higher one)."""
    a, b = _pair(mu=0.1), _pair(mu=0.1, swap=True)
    assert torch.allclose(a[0], b[0], atol=1e-12) and torch.allclose(a[1], b[1], atol=1e-12)


def test_contact_needs_both_bands_and_an_approach():
    """No impulse when one field's band mass is at or below eps_b, or when the fields separate."""
    for band in ((1.0, 0.5), (0.5, 1.0)):
        v0, v1 = _pair(mu=10.0, band=band)
        assert v0.tolist() == [0.0, 0.0, 0.0] and v1.tolist() == [0.5, 0.0, -1.0]
    v = torch.tensor([[[0.0, 0.0, 0.0], [0.5, 0.0, 1.0]]], dtype=torch.float64)  # moving apart
    out = contact_fields(
        v, torch.tensor([[1.0, 3.0]]), torch.tensor([[0, 1]]), torch.ones(1, 2), 1e-9, 0.5, lambda *a: N, mu=1.0
    )
    assert torch.equal(out, v)


def test_reference_stencil_reproduces_linear_fields_and_the_apic_inertia(seed):
    """The quadratic B-spline stencil: weights sum to 1, Σ w (x_i − x_p) = 0, Σ ∇w = 0, Σ (x_i − x_p) ⊗ ∇w = I
        (a linear field's gradient is exact), and Σ w (x_i − x_p)(x_i − x_p)ᵀ = Δx²/4 · I (the APIC inertia
        behind C = 4/Δx² Σ w v (x_i − x_p)ᵀ), at random positions; every weight is non-negative and every node within
    the spline's support, 1.5Δx per axis (the identities alone also hold for a stencil one node off)."""
    g = torch.Generator().manual_seed(seed)
    dx = 0.125
    x = 0.3 + torch.rand(50, 3, generator=g, dtype=torch.float64)
    nodes, w, grad, dpos = stencil(x, (-0.25, 0.0, 0.125), dx)
    eye = torch.eye(3, dtype=torch.float64).expand(50, 3, 3)
    assert torch.allclose(w.sum(1), torch.ones(50, dtype=torch.float64), atol=1e-12)
    assert float((w[..., None] * dpos).sum(1).abs().max()) < 1e-12
    assert float(grad.sum(1).abs().max()) < 1e-10
    assert torch.allclose(torch.einsum("nki,nkj->nij", dpos, grad), eye, atol=1e-10)
    D = torch.einsum("nk,nki,nkj->nij", w, dpos, dpos)
    assert torch.allclose(D, dx * dx / 4 * eye, atol=1e-12)
    xi = nodes.double() * dx + torch.tensor([-0.25, 0.0, 0.125], dtype=torch.float64)
    assert torch.allclose(xi - x[:, None, :], dpos, atol=1e-12)  # offsets are node minus particle
    assert bool((w >= 0).all()) and float(dpos.abs().max()) <= 1.5 * dx  # the spline's support: 1.5Δx


def test_reference_two_field_contact_restitutes_and_conserves_momentum():
    """`contact`: approaching fields (masses 1 and 3, u_n = −1) leave with u_n = +e and unchanged total
    momentum; separating ones are untouched."""
    v0 = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], dtype=torch.float64)
    v1 = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    m0, m1 = torch.tensor([1.0, 1.0], dtype=torch.float64), torch.tensor([3.0, 3.0], dtype=torch.float64)
    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    w0, w1 = contact(v0, v1, m0, m1, n, e=0.5)
    assert abs(float((w1[0] - w0[0]) @ n) - 0.5) < 1e-12
    assert torch.allclose(m0[0] * w0[0] + m1[0] * w1[0], m1[0] * v1[0], atol=1e-12)
    assert torch.equal(w0[1], v0[1]) and torch.equal(w1[1], v1[1])


def test_reference_grid_update_normalizes_and_adds_gravity_only_on_active_nodes():
    """grid_update: v = p/m + Δt·g where m > eps_m, 0 elsewhere (an empty node, or one holding exactly eps_m,
    never falls)."""
    gm = torch.tensor([[2.0, 1e-12, 0.5]], dtype=torch.float64).reshape(1, 3, 1, 1)
    gp = torch.tensor([[[1.0, 0.0, 0.0], [5.0, 5.0, 5.0], [0.0, 0.0, 1.0]]], dtype=torch.float64).reshape(1, 3, 1, 1, 3)
    v = grid_update(gm, gp, torch.zeros_like(gm), 1e-9, 0.5, 0.01, (0.0, 0.0, -10.0)).reshape(3, 3)
    at_eps = grid_update(gm, gp, torch.zeros_like(gm), 0.5, 0.5, 0.01, (0.0, 0.0, -10.0)).reshape(3, 3)
    assert at_eps[2].tolist() == [0.0, 0.0, 0.0] and torch.allclose(at_eps[0], v[0])
    assert torch.allclose(v[0], torch.tensor([0.5, 0.0, -0.1], dtype=torch.float64))
    assert v[1].tolist() == [0.0, 0.0, 0.0]
    assert torch.allclose(v[2], torch.tensor([0.0, 0.0, 1.9], dtype=torch.float64))
