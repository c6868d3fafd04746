"""`sim/diff/reference.py`, the float64 twin of a differentiable frame, with two fragment fields: without contact
(`spec.contact` false) the fields never meet, so a two-field frame moves every particle exactly as running each
fragment alone in a one-field frame does (superposition), even where the two fragments share grid nodes and move
into each other; with contact the approach at the shared band nodes is projected away, so the fragments' relative
normal speed drops below what they had."""

from __future__ import annotations

import types

import torch

from fracture_gs.sim.diff import reference as DR
from fracture_gs.sim.diff.solver import FramePlan

DX = 1.0 / 16


def scene():
    """Fragment 0 (x in nodes 6-8) moving +x and fragment 1 (x in nodes 7-9) moving -x at 0.5 m/s, overlapping,
    unstressed (F = I), every particle in the band; no gravity."""
    g = torch.Generator().manual_seed(7)
    n = 48
    x0 = (torch.tensor([6.0, 6.0, 6.0]) + 2.0 * torch.rand(n, 3, generator=g)) * DX
    x1 = (torch.tensor([7.0, 6.0, 6.0]) + 2.0 * torch.rand(n, 3, generator=g)) * DX
    x = torch.cat([x0, x1])
    v = torch.zeros(2 * n, 3)
    v[:n, 0], v[n:, 0] = 0.5, -0.5
    C = torch.zeros(2 * n, 3, 3)
    F = torch.eye(3).expand(2 * n, 3, 3).clone()
    fragment = torch.cat([torch.zeros(n, dtype=torch.int32), torch.ones(n, dtype=torch.int32)])
    mu, lam = torch.full((2 * n,), 3e3, dtype=torch.float64), torch.full((2 * n,), 2e3, dtype=torch.float64)
    mass, volume = torch.full((2 * n,), 1e-3), torch.full((2 * n,), 1e-6)
    return x, v, C, F, mu, lam, mass, volume, fragment


def sim(contact: bool, n: int):
    return types.SimpleNamespace(
        eps=(1e-12, 1e-12),
        _normal=lambda plan: (1.0, 0.0, 0.0),
        material=torch.zeros(n, dtype=torch.int32),
        dx=DX,
        origin=(0.0, 0.0, 0.0),
        cfg=types.SimpleNamespace(
            gravity=(0.0, 0.0, 0.0), restitution=0.0, contact=types.SimpleNamespace(friction=0.0)
        ),
        spec=types.SimpleNamespace(contact=contact),
    )


def plan(field: torch.Tensor, fields: int) -> FramePlan:
    n = field.shape[0]
    return FramePlan(
        n=3,
        dt=1e-3,
        t0=0.0,
        field=field,
        released=torch.ones(n),
        band=torch.ones(n),
        fields=fields,
        lo=(0, 0, 0),
        shape=(16, 16, 16),
    )


def test_without_contact_two_fields_are_each_fragment_alone():
    """spec.contact false, K = 2: x, v, C and F of each fragment after three substeps equal a one-field frame of
    that fragment alone (float64 rounding); the fragments did approach (their mean x velocities stay ±0.5 m/s)."""
    x, v, C, F, mu, lam, mass, volume, frag = scene()
    both = DR.frame(sim(False, len(x)), plan(frag, 2), x, v, C, F, mu, lam, mass, volume)
    for k in (0, 1):
        m = frag == k
        alone = DR.frame(
            sim(False, int(m.sum())),
            plan(torch.zeros(int(m.sum()), dtype=torch.int32), 1),
            *(t[m] for t in (x, v, C, F, mu, lam, mass, volume)),
        )
        for a, b in zip(both, alone):
            assert torch.allclose(a[m], b, rtol=0, atol=1e-12)
    assert abs(float(both[1][frag == 0, 0].mean()) - 0.5) < 1e-9
    assert abs(float(both[1][frag == 1, 0].mean()) + 0.5) < 1e-9


def test_with_contact_the_approach_is_projected_away():
    """spec.contact true, K = 2, restitution 0: at the shared band nodes the fields' approach along the latched
    normal x is removed, so the fragments' relative x velocity (1 m/s before) drops below half and no
    particle speeds up along x."""
    x, v, C, F, mu, lam, mass, volume, frag = scene()
    out = DR.frame(sim(True, len(x)), plan(frag, 2), x, v, C, F, mu, lam, mass, volume)
    vx = out[1][:, 0]
    closing = float(vx[frag == 0].mean() - vx[frag == 1].mean())
    assert closing < 0.5
    assert float(vx[frag == 0].max()) <= 0.5 + 1e-9 and float(vx[frag == 1].min()) >= -0.5 - 1e-9
