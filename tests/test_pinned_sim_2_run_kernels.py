"""P2G in runs (`sim.grid.run_kernels.p2g_runs`) on a multi-field grid: a thread whose particles all take the slot
path (none solo) has no run to flush and writes nothing. Warp wraps a negative array index to the end of the
array, so an empty run flushed at node (−1, −1, −1) would land in the pool's last rows; those are filled with
−0.0 first (which adding even +0.0 turns into +0.0), so any such write shows."""

from dataclasses import replace

import torch
from test_transfer_launch import slab

from fracture_gs import sim as S
from fracture_gs.sim.grid.layout import EMPTY_KEY


def test_runs_without_a_solo_particle_write_nothing_into_unclaimed_pool_rows():
    """A cell-sorted slab cut near one end, runs of 4 particles with the fan-out taking the listed ones: after a
    P2G, every pool row no node claimed still holds the −0.0 it was given (no thread flushed an empty run), and
    the grid holds every particle's mass."""
    sim, _ = slab(0, "cpu", sort="cell")
    sim.options = replace(sim.options, fanout=True, p2g_run=4)
    sim.latch(S.Topology.from_plane(sim.particles.x.cpu(), (0.18, 0.5, 0.5), (1.0, 0.2, 0.1), band_width=1.5 / 32))
    sim.advance(5e-3)
    assert sim.slots.run_length(1) == 4
    solo = sim.slots.solo.cpu().view(-1)
    runs = solo[: len(solo) // 4 * 4].view(-1, 4)
    assert bool((runs == 0).all(1).any()), "some run has no solo particle"
    g = sim.grid
    g.reset_claims()
    g._mp[g.n_nodes :] = -0.0
    sim.counts.zero_()
    sim.compute_stress(sim.stress, commit=False)
    sim.p2g(1e-3)
    free = torch.nonzero(g.key.cpu() == EMPTY_KEY).flatten()
    assert len(free) > 0.5 * g.capacity
    rows = g._mp[g.n_nodes :].view(g.capacity, g.slots - 1, 4)[free]
    assert bool(torch.signbit(rows).all()), "P2G wrote into a pool row no node claimed"
    total = float(g._mp[:, 3].double().sum())
    assert abs(total - float(sim.particles.mass.double().sum())) < 1e-4 * total
