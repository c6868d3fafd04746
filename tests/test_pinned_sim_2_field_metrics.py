"""Field statistics of the slot storage (`sim.grid.field_metrics_kernels`, launched by `Grid.field_sums`): the
counterfactual mixing of a node is Σ_k m^k ‖v̄ − v^k‖² about the node's mass-weighted mean velocity v̄, with every
component of every field's momentum, slot 0's included."""

import pytest
import torch
from simutil import fill_slots

from fracture_gs.sim.grid.fields import Grid


def test_mixing_uses_all_three_momentum_components_of_slot_zero():
    """Two fields on a 6³ grid: field 0 (slot 0) everywhere at (0.5, 0, 2) m/s, mass 1; field 1 (a pool slot)
    on i < 3 at (0, 1, 0) m/s, mass 3. At a shared node v̄ = (m₀v₀ + m₁v₁)/(m₀ + m₁) and the mixing
    Σ_k m_k ‖v̄ − v_k‖² = m₀m₁/(m₀ + m₁) ‖v₀ − v₁‖² = ¾ · 5.25; summed over the 108 shared nodes and divided by the
    total mass 216 + 324."""
    s, eps = 6, 1e-9
    g = Grid((0.0, 0.0, 0.0), 1.0 / s, (s, s, s), "cpu", slots=2)
    g.ensure_pool(s**3)
    i = torch.arange(s)[:, None, None].expand(s, s, s)
    m = torch.zeros(2, s, s, s, dtype=torch.float64)
    m[0] = 1.0
    m[1][i < 3] = 3.0
    vel = torch.tensor([[0.5, 0.0, 2.0], [0.0, 1.0, 0.0]], dtype=torch.float64)
    fill_slots(g, m, vel[:, None, None, None, :].expand(2, s, s, s, 3))
    g.n_fields = 2
    want = 108 * (1.0 * 3.0 / 4.0) * (0.25 + 1.0 + 4.0) / (216 + 324)
    cf, pct, mass = g.field_sums(eps, 2)
    assert float(cf) == pytest.approx(want, rel=1e-5)
    assert float(pct) == pytest.approx(50.0)
    assert mass.tolist() == pytest.approx([216.0, 324.0])
