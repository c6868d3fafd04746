"""G2P's fan-out (`sim.grid.fanout_kernels.g2p_fanout`) with `one_gather`: the listed (not solo) particles and, in the
same launch behind them, every solo particle are gathered; the result is the one of the two launches
(fan-out for the listed, the plain G2P for the solo particles), particle by particle, the first particle
included."""

from dataclasses import replace

import torch
from test_transfer_launch import slab

from fracture_gs import sim as S


def test_one_gather_moves_every_particle_as_two_launches_do():
    """A slab under gravity cut near one end (the band's particles listed, the rest solo; the fan-out taken however many
    are listed), one frame of 5 ms with the
    solo particles in the fan-out's launch and with them in their own launch: every particle's x and v agree
    to float32 rounding, and particle 0 (solo, the first thread behind the listed ones) has fallen."""
    out = []
    for one in (False, True):
        sim, _ = slab(0, "cpu")
        sim.options = replace(sim.options, fanout=True, one_gather=one, g2p_fanout_max=1.0)
        sim.latch(S.Topology.from_plane(sim.particles.x.cpu(), (0.18, 0.5, 0.5), (1.0, 0.2, 0.1), band_width=1.5 / 32))
        v0 = sim.particles.v[0].clone()
        sim.advance(5e-3)
        assert sim.slots.fans_out(1, -1, gather=True), "the fan-out gathers this frame"
        assert int(sim.slots.solo[0]) == 1
        out.append((sim.particles.x.cpu().clone(), sim.particles.v.cpu().clone(), v0))
    (x0, v0, _), (x1, v1, start) = out
    torch.testing.assert_close(x1, x0, rtol=0.0, atol=1e-6)
    torch.testing.assert_close(v1, v0, rtol=0.0, atol=1e-5)
    assert float(v1[0, 2] - start[2]) < -0.02, "particle 0 gained downward speed under gravity"
