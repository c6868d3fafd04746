"""The counterfactual mixing of the slot storage's fields at any mass (`Grid.field_sums`, its kernels, and the twin
`Grid.mixing`).

E_mix / Σm = Σ_i Σ_k m_i^k ‖v̄_i − v_i^k‖² / Σ_i Σ_k m_i^k, v̄_i = Σ_k p_i^k / Σ_k m_i^k, over the fields above ε_m.
It depends on the fields' mass *ratios* and velocities only: two fields of masses m₀, m₁ at every node give
m₀m₁/(m₀ + m₁)² ‖v₀ − v₁‖², the same for kilograms as for 1e-31 kg (a node at the edge of a particle's stencil,
with ε_mass = 0). A guard value in v̄'s or the ratio's denominator (once max(M, 1e-30) and Σm + 1e-30) bent light
nodes: two fields moving together read as mixing. Fields moving together never mix; an empty grid reads 0.
"""

from __future__ import annotations

import pytest
import torch
from simutil import fill_slots

from fracture_gs.sim.grid.fields import Grid

S = 5  # a 5³ grid (the smallest a grid may be): every node holds both fields


def _grid(m0: float, m1: float, v0, v1) -> Grid:
    g = Grid((0.0, 0.0, 0.0), 0.25, (S, S, S), "cpu", slots=2)
    g.ensure_pool(S**3)
    m = torch.tensor([m0, m1], dtype=torch.float64)[:, None, None, None].expand(2, S, S, S)
    v = torch.tensor([v0, v1], dtype=torch.float64)[:, None, None, None, :].expand(2, S, S, S, 3)
    fill_slots(g, m.contiguous(), v.contiguous())
    return g


@pytest.mark.parametrize("scale", [1.0, 1e-31])
def test_the_mixing_ratio_depends_on_mass_ratios_only(scale):
    """m₀ = 3, m₁ = 1 (times 1 kg or 1e-31 kg) at v₀ = (1, 0, 2), v₁ = (−1, 0.5, 2) m/s at all 125 nodes, ε_m = 0:
    E_mix / Σm = (3·1/4²)·‖v₀ − v₁‖² = 3/16 · 4.25 m²/s², from the kernels and from the twin; both fields active
    at every node, so the shared support is 100 %."""
    g = _grid(3.0 * scale, 1.0 * scale, (1.0, 0.0, 2.0), (-1.0, 0.5, 2.0))
    want = 3.0 / 16.0 * 4.25
    cf, shared, mass = g.field_sums(0.0, 2)
    assert float(cf) == pytest.approx(want, rel=1e-5)
    assert float(shared) == 100.0
    assert mass.tolist() == pytest.approx([125 * 3.0 * scale, 125 * 1.0 * scale], rel=1e-6)
    twin, twin_shared = g.mixing(0.0)
    assert float(twin) == pytest.approx(want, rel=1e-5) and float(twin_shared) == 100.0


@pytest.mark.parametrize("scale", [1.0, 1e-31])
def test_fields_moving_together_do_not_mix_however_light(scale):
    """Both fields at (1, −2, 0.5) m/s: v̄ = v₀ = v₁, so E_mix is 0 up to the float32 rounding of the stored
    momenta (below 1e-12 m²/s² against the ≈ 0.3 a 1e-30 kg guard in v̄ would read at 1e-31 kg)."""
    g = _grid(3.0 * scale, 1.0 * scale, (1.0, -2.0, 0.5), (1.0, -2.0, 0.5))
    cf, _, _ = g.field_sums(0.0, 2)
    twin, _ = g.mixing(0.0)
    assert abs(float(cf)) < 1e-12 and abs(float(twin)) < 1e-12


def test_fields_below_eps_m_take_no_part_and_an_empty_grid_reads_zero():
    """With ε_m above the light fields' masses neither field is active: no mixing, no shared support. A grid
    without mass reads 0 (not 0/0) from the kernels and from the twin."""
    g = _grid(3e-31, 1e-31, (1.0, 0.0, 2.0), (-1.0, 0.5, 2.0))
    cf, shared, _ = g.field_sums(1e-20, 2)
    assert (float(cf), float(shared)) == (0.0, 0.0)
    empty = _grid(0.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    for cf, shared in (empty.field_sums(0.0, 2)[:2], empty.mixing(0.0)):
        assert (float(cf), float(shared)) == (0.0, 0.0)
