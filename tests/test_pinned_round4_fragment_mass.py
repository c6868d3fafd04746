"""`Grid.fragment_mass(K)` and the mass column of `Grid.field_sums(eps, K)` sum the grid mass of fragments
k < K only: a field of a fragment ≥ K, in slot 0 or in a pool slot, is left out, never folded into fragment
K − 1 (its id clamped). Four fields written straight into a 6³ grid's slots: slot 0 holds fragment 0 on the
nodes with i < 3 and fragment 3 on the others; fragments 1 and 2 sit in pool slots everywhere. Both the torch
twin and the two Warp launches must give the hand sums for K = 1 … 5."""

from __future__ import annotations

import pytest
import torch
from simutil import fill_slots

from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import ROW_FLAG

S = 6


def _grid():
    g = Grid((0.0, 0.0, 0.0), 1.0 / S, (S, S, S), "cpu", slots=4)
    g.ensure_pool(S**3)
    m = torch.zeros(3, S, S, S, dtype=torch.float64)
    m[0] = 1.0
    m[1] = 2.0
    m[2] = 0.5
    fill_slots(g, m, torch.zeros(3, S, S, S, 3, dtype=torch.float64))
    # slot 0 of the nodes i ≥ 3 holds fragment 3 instead of fragment 0 (owner word: fragment id + 1)
    i = torch.arange(S)[:, None, None].expand(S, S, S).reshape(-1)
    g._owner[i >= 3] = (3 + 1) | ROW_FLAG
    g.n_fields = 4
    half = S**3 / 2
    per_fragment = [1.0 * half, 2.0 * S**3, 0.5 * S**3, 1.0 * half]  # [kg] fragments 0, 1, 2, 3
    return g, per_fragment


@pytest.mark.parametrize("K", [1, 2, 3, 4, 5])
def test_fragment_masses_below_k_only_in_both_twins(K):
    """fragment_mass(K) and field_sums(ε, K)'s masses are the hand sums of fragments 0 … K − 1 (zero for a
    fragment with no field): 108, 432, 108, 108 kg-units for fragments 0-3; fragment 3 (slot 0) and fragment 2
    (pool) vanish below their ids instead of landing on fragment K − 1."""
    g, per_fragment = _grid()
    expected = torch.tensor((per_fragment + [0.0])[:K], dtype=torch.float64)
    torch.testing.assert_close(g.fragment_mass(K).cpu(), expected, rtol=1e-6, atol=0.0)
    _, _, mass = g.field_sums(1e-9, K)
    torch.testing.assert_close(mass.cpu(), expected, rtol=1e-6, atol=0.0)
