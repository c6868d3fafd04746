"""G2P's fan-out (`sim.fanout_kernels.g2p_fanout`): on CUDA the 32 lanes of one warp share a listed particle and
`lane_sum`'s butterfly shuffles add up exactly those 32 lanes, so a particle's lanes must be one whole warp,
aligned: LANES = 32 = twice the butterfly's first offset, and the launch gives each listed particle LANES
threads (capacity · LANES of them, `listed` = that count) and each solo particle one thread behind them. Whatever
the device, the fan-out moves every particle as the plain G2P does (`--device cuda` runs the shuffles)."""

import dataclasses
import re

import torch
from test_transfer_launch import slab

from fracture_gs import sim as S
from fracture_gs.sim.grid import fanout_kernels


def test_one_listed_particle_takes_one_whole_warp():
    """The butterfly in `_LANE_SUM` starts at offset 16 and halves to 1 under the full 32-bit mask: it sums
    2 · 16 = 32 lanes, and LANES is that number."""
    first = re.search(r"for \(int o = (\d+); o > 0; o >>= 1\)", fanout_kernels._LANE_SUM)
    assert first is not None and "0xffffffffu" in fanout_kernels._LANE_SUM
    assert fanout_kernels.LANES == 2 * int(first.group(1)) == 32


def _cut_slab(device, fanout):
    sim, _ = slab(0, device)
    sim.options = dataclasses.replace(sim.options, fanout=fanout, g2p_fanout_max=1.0)
    sim.latch(S.Topology.from_plane(sim.particles.x.cpu(), (0.18, 0.5, 0.5), (1.0, 0.2, 0.1), band_width=1.5 / 32))
    return sim


def test_fanout_gather_launches_a_warp_per_listed_particle_and_matches_the_plain_gather(device):
    """A slab cut near one end, one frame of one 1 ms substep with the fan-out and without it: the fan-out's G2P
    launch covers 32 · capacity threads for the listed particles plus one per particle, with `listed` = 32 ·
    capacity; and every particle's x and v agree with the plain G2P's to float32 rounding."""
    sim = _cut_slab(device, True)
    seen = []
    plain_launch = sim.launch

    def record(kernel, dim, inputs):
        if kernel is fanout_kernels.g2p_fanout:
            seen.append((dim, inputs[-1]))
        plain_launch(kernel, dim, inputs)

    sim.launch = record
    sim.advance(1e-3)
    assert seen, "the fan-out gathered"
    cap, n = sim.slots.fan_cap, len(sim.particles)
    assert cap > 0 and all(s == (32 * cap + n, 32 * cap) for s in seen), (seen, cap, n)
    other = _cut_slab(device, False)
    other.advance(1e-3)
    for name in ("x", "v"):
        a, b = getattr(other.particles, name).cpu(), getattr(sim.particles, name).cpu()
        torch.testing.assert_close(b, a, rtol=0.0, atol=1e-5)
