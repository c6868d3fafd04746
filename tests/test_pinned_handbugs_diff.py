"""Hand-written bug campaign, differentiable path (`sim.diff`): rules the earlier tests left open.

- Free fall is exact in MLS-MPM: a stress-free block with one velocity v₀ deposits a uniform velocity field, so
  after a frame of length T under gravity every particle moves at v₀ + g T, including the ones at the block's
  edge whose nodes hold little mass. That holds for any field-activity threshold ε_m below the lightest node's
  mass; the contact gate ε_b (`sim.eps_band`) plays no part without fragments. With eps_band = 0.5 (half a full
  node) a solver that took ε_b for ε_m would zero the light edge nodes and slow the edge particles down.
"""

import torch
from simutil import block, config

from fracture_gs.sim.diff.solver import DiffSimulator

G, T, RHO = 9.8, 0.01, 100.0


def test_a_falling_block_moves_as_one_whatever_the_contact_gate():
    """A 0.1 m cube of resting particles (E = 0: no stress), one frame of 0.01 s at Δt = 2.5 ms under
    g = (0, 0, −9.8): every particle's velocity is (0.5, 0, 0.2) + (0, 0, −0.098) to float32 rounding."""
    x, vol = block((0.45, 0.45, 0.45), (0.55, 0.55, 0.55), 1.0 / 64)
    n = x.shape[0]
    cfg = config(32, variant="baseline", dt=2.5e-3, gravity=(0.0, 0.0, -G), eps_band=0.5)
    sim = DiffSimulator(cfg, x)
    v0 = torch.tensor([0.5, 0.0, 0.2]).expand(n, 3).contiguous()
    zeros = torch.zeros(n)
    C = torch.zeros(n, 3, 3)
    F = torch.eye(3).expand(n, 3, 3).contiguous()
    mass, volume = torch.full((n,), RHO * vol), torch.full((n,), vol)
    _, v, _, _ = sim.step(T, x, v0, C, F, zeros, zeros, mass, volume)
    expected = torch.tensor([0.5, 0.0, 0.2 - G * T])
    assert float((v - expected).abs().max()) < 1e-5
