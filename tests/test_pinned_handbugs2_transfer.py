"""Hand-written bug campaign, round two: the MLS-MPM transfer's bookkeeping (`sim.stencil.finish_g2p`).

G2P clamps a particle's new position into [node c − 1, node n − c] per axis (c = wall_cells) and counts every
particle it clamped, on each axis and at each side: 8 particles 0.3 Δx inside one clamp bound moving out at
100 m/s (two of their three stencil nodes along that axis are wall nodes, the third carries weight 0.32: 32 m/s,
0.5 Δx in a 0.5 ms substep) are all clamped and counted in one substep, whichever of the six walls it is.
"""

import pytest
import torch
from simutil import config, particles

from fracture_gs import sim as S

N, C, DX = 32, 3, 1 / 32


@pytest.mark.parametrize("side", [-1, 1])
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_clamp_is_counted_on_every_axis_and_side(axis, side):
    """Axis `axis`, wall `side` (−1 lower, +1 upper): 8 particles at the bound ∓ 0.3 Δx moving out end on the bound,
    and clamped_count() is 8."""
    bound = (C - 1) * DX if side < 0 else (N - C) * DX
    x = torch.full((8, 3), 0.5)
    x[:, (axis + 1) % 3] = torch.linspace(0.3, 0.7, 8)
    x[:, axis] = bound - side * 0.3 * DX
    v = torch.zeros(3)
    v[axis] = 100.0 * side
    sim = S.Simulator(config(N, dt=5e-4, wall_cells=C), particles(x, 1e-6, v=v.expand(8, 3)))
    sim.substep()
    assert torch.allclose(sim.particles.x[:, axis], torch.full((8,), bound))
    assert sim.clamped_count() == 8


def _two_fields_sim():
    """Two blocks side by side along x, cut between them, latched normals (n_Π = +x), slot storage with a pool row
    at every node of an 8³ grid, no walls, no gravity."""
    from simutil import block

    a, vol = block((0.3, 0.4, 0.4), (0.45, 0.6, 0.6), 0.025)
    b, _ = block((0.55, 0.4, 0.4), (0.7, 0.6, 0.6), 0.025)
    cfg = S.SimConfig(dx=1 / 8, grid_shape=(8, 8, 8), gravity=(0, 0, 0), variant="full", wall_cells=0,
                      field_slots=4, contact=S.ContactConfig(normal="latched"), grid_storage="slots")  # fmt: skip
    sim = S.Simulator(cfg, particles(torch.cat([a, b]), vol), device="cpu")
    sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 0.0))
    sim.grid.ensure_pool(2 * sim.grid.n_nodes)
    return sim


@pytest.mark.parametrize("band0,band1,touch", [(1, 1, True), (1, 0, False), (0, 1, False), (0, 0, False)])
def test_the_band_gate_needs_band_mass_in_both_fields(band0, band1, touch):
    """Two fields of equal mass m = ρ̄Δx³ at every node approach along n_Π = +x (v⁰ = (1, 1/2, 0), v¹ = (−1, 0, 1/4)).
    With band mass m in both fields they are in contact: frictionless, e = 0, each takes the mean normal velocity,
    v⁰ = (0, 1/2, 0), v¹ = (0, 0, 1/4). With band mass in one field only, or none, they pass untouched."""
    from simutil import fill_slots

    sim = _two_fields_sim()
    shape = sim.grid.shape
    m = torch.full((2, *shape), sim.node_mass, dtype=torch.float64)
    v = torch.tensor([[1.0, 0.5, 0.0], [-1.0, 0.0, 0.25]], dtype=torch.float64)[:, None, None, None, :]
    band = torch.stack([m[0] * band0, m[1] * band1])
    fill_slots(sim.grid, m, v.expand(2, *shape, 3), band)
    sim.update_grid(1e-3)
    got = sim.grid.velocity.double().cpu()[:2]  # [2, X, Y, Z, 3]
    want = torch.tensor([[0.0, 0.5, 0.0], [0.0, 0.0, 0.25]] if touch else [[1.0, 0.5, 0.0], [-1.0, 0.0, 0.25]])
    assert torch.allclose(got, want.double()[:, None, None, None, :].expand_as(got), atol=1e-5)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_p2g_counts_a_stencil_that_leaves_the_active_box_on_either_side(axis):
    """A particle at ξ = 16.2 (Δx = 1/32) has stencil nodes 15, 16, 17 on every axis. The active box [lo, hi) holds
    it with lo = 15 and hi = 18; with hi = 17 (node 17 outside) or lo = 16 (node 15 outside) on one axis, P2G
    counts it as escaped, exactly once."""
    from fracture_gs.sim.storage import COUNT_ESCAPED

    sim = S.Simulator(config(N, wall_cells=0), particles(torch.full((1, 3), 16.2 / 32), 1e-6))
    for lo, hi, escaped in ((15, 18, 0), (15, 17, 1), (16, 18, 1)):
        box = [15, 15, 15, 18, 18, 18]
        box[axis], box[3 + axis] = lo, hi
        sim.slots.set_box(tuple(box))
        sim.counts.zero_()
        sim.p2g(1e-3)
        assert int(sim.counts[COUNT_ESCAPED]) == escaped, f"box {box}"
