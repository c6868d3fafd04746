"""The differentiable solver's host-side set-up (no kernel runs): the box its G2P clamps particles into
keeps the same wall thickness on both sides of every axis, and a frame's plan takes up to eight fragments
(one more is refused with a sentence naming the limit)."""

import pytest
import torch
from simutil import block, config

from fracture_gs.errors import SimulationError
from fracture_gs.sim.diff import DiffSimulator
from fracture_gs.sim.topology import Topology


def test_the_particle_clamp_box_is_as_far_from_the_last_node_as_from_the_first():
    """On a 24 × 32 × 40 grid with 3 wall cells and Δx = 1/32, particles are clamped to
    [origin + 2Δx, origin + (shape − 3)Δx] per axis: the upper bound sits (wall_cells − 1)Δx below the last
    node (index shape − 1) exactly as the lower sits above the first (the walls are equally thick)."""
    dx, shape, origin = 1.0 / 32, (24, 32, 40), (0.25, -0.5, 1.0)
    cfg = config(32, wall_cells=3)
    cfg.grid_shape, cfg.grid_origin = shape, origin
    x, _ = block((0.4, -0.3, 1.3), (0.6, -0.1, 1.5), dx)
    sim = DiffSimulator(cfg, x, "cpu")
    lo, hi = tuple(sim._lower), tuple(sim._upper)
    for a in range(3):
        first, last = origin[a], origin[a] + (shape[a] - 1) * dx
        assert lo[a] - first == pytest.approx(2 * dx, abs=1e-6)
        assert last - hi[a] == pytest.approx(2 * dx, abs=1e-6)


def _cut(x, k):
    """x labelled into k slabs along x (fragment i = the i-th slab), latched at frame 0."""
    lo, hi = float(x[:, 0].min()), float(x[:, 0].max())
    fragment = ((x[:, 0] - lo) / (hi - lo + 1e-9) * k).long().clamp_max(k - 1).to(torch.int32)
    band = torch.zeros(len(x), dtype=torch.int32)
    return Topology(fragment=fragment, band=band, normal=(1.0, 0.0, 0.0), point=(0.5, 0.5, 0.5), latch_frame=0)


def test_a_frame_takes_eight_fragments_and_refuses_nine():
    """The differentiable path holds up to 8 fragments: a topology of 8 slabs plans 8 fields; one of 9 is
    refused with a SimulationError that names the limit."""
    x, _ = block((0.3, 0.4, 0.4), (0.7, 0.5, 0.5), 1.0 / 32)
    sim = DiffSimulator(config(32, variant="full", dt=1e-3), x, "cpu", topologies=[_cut(x, 8)])
    sim._x = x
    assert sim.plan(0, torch.zeros_like(x), 0.01, 0.0).fields == 8
    sim = DiffSimulator(config(32, variant="full", dt=1e-3), x, "cpu", topologies=[_cut(x, 9)])
    sim._x = x
    with pytest.raises(SimulationError, match="up to 8 fragments"):
        sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
