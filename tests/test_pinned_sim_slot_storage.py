"""`sim/grid/slots.py` host decisions, on a stand-in simulator: the solo flags and launch order, the
fan-out capacity (the next power of two of the particles that are not solo, at least 256, at most all
of them; none when nobody needs it), when the fan-out and P2G's runs are used, and the solo reach."""

import types

import torch

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.slots import SlotStorage
from fracture_gs.sim.options import SimOptions


class Host:
    """The few simulator attributes the slot storage's host decisions read."""

    def __init__(self, particles, grid, multifield=True, **switches):
        self.particles, self.grid, self.multifield, self.device = particles, grid, multifield, "cpu"
        self.options = SimOptions(**switches)


class Particles:
    def __init__(self, x, fragment):
        self.x, self.fragment = x, fragment

    def __len__(self):
        return len(self.x)


def _host(n, fanout=True, slow_first=True, multifield=True, fanout_max=0.25, run=4):
    ensure_warp()  # set_solo wraps the slot cache for Warp
    grid = types.SimpleNamespace(shape=(8, 8, 8))
    host = Host([0] * n, grid, multifield, fanout=fanout, slow_first=slow_first, g2p_fanout_max=fanout_max, p2g_run=run)
    return SlotStorage(host), host


def _mask(n, slow):
    """Solo flags with the particles listed in `slow` not solo."""
    m = torch.ones(n, dtype=torch.int32)
    m[list(slow)] = 0
    return m


def test_launch_order_lists_the_particles_that_are_not_solo_first():
    """set_solo: the order holds the particles that are not solo first (in index order), then the solo
    ones, and `_first` counts the former, with slow_first or fanout on."""
    h, _ = _host(8)
    h.set_solo(_mask(8, [5, 1, 6]))
    assert h.order.tolist() == [1, 5, 6, 0, 2, 3, 4, 7]
    assert int(h.first) == 3 and h.slow == 3
    for fanout, slow_first in ((False, True), (True, False)):  # either one needs the order
        h, _ = _host(8, fanout=fanout, slow_first=slow_first)
        h.set_solo(_mask(8, [7, 2]))
        assert h.order.tolist()[:2] == [2, 7] and int(h.first) == 2


def test_fanout_capacity_is_the_next_power_of_two_of_the_slow_particles():
    """Fan-out capacity: the next power of two ≥ the particles that are not solo, at least 256 and at most
    every particle; the slot cache holds 27 entries per fan-out slot."""
    for n, slow, cap in ((5000, 300, 512), (5000, 10, 256), (5000, 256, 256), (5000, 257, 512), (3000, 2500, 3000)):
        h, _ = _host(n)
        h.set_solo(_mask(n, range(slow)))
        assert h.fan_cap == cap, (n, slow)
        assert h.slot_cache.numel() == 27 * cap


def test_no_fanout_when_every_particle_is_solo_or_the_flags_are_cleared():
    """Nobody to fan out (every particle solo), the flags cleared (None: every particle takes the slot path,
    but the fan-out waits for the next frame's flags), or a single-field grid: capacity 0, no fan-out
    launch, a one-entry slot cache."""
    h, _ = _host(1000)
    h.set_solo(torch.ones(1000, dtype=torch.int32))
    assert h.fan_cap == 0 and h.slow == 0 and h.slot_cache.numel() == 1
    assert not h.fans_out(1, -1)
    h, _ = _host(1000)
    h.set_solo(None)
    assert h.fan_cap == 0 and h.slow == 1000 and int(h.solo.sum()) == 0
    h, _ = _host(1000, multifield=False)
    h.set_solo(_mask(1000, range(10)))
    assert h.fan_cap == 0


def test_fanout_runs_only_on_multifield_grids_outside_the_fragment_pass_and_for_few_particles_in_g2p():
    """fans_out: multi-field, all fragments (only_fragment < 0), a fan-out capacity; in G2P also at most
    g2p_fanout_max of the particles not solo (exactly that fraction still fans out)."""
    h, host = _host(1000, fanout_max=0.25)
    h.set_solo(_mask(1000, range(250)))
    assert h.fans_out(1, -1) and h.fans_out(1, -1, gather=True)
    assert not h.fans_out(0, -1)
    assert not h.fans_out(1, 0)
    h.set_solo(_mask(1000, range(251)))
    assert h.fans_out(1, -1) and not h.fans_out(1, -1, gather=True)
    host.options = SimOptions(fanout=False, slow_first=True, g2p_fanout_max=0.25, p2g_run=4)
    assert not h.fans_out(1, -1)


def test_p2g_runs_stop_when_more_than_half_take_the_slot_path():
    """P2G's run length is p2g_run on a single-field grid or while at most half the particles are not solo,
    0 (one particle per thread) beyond half; G2P splits the launch only with slow_first on a multi-field
    grid."""
    h, host = _host(1000, run=4)
    h.slow = 500
    assert h.run_length(1) == 4
    h.slow = 501
    assert h.run_length(1) == 0 and h.run_length(0) == 4
    assert h.split(1) and not h.split(0)
    host.options = SimOptions(fanout=True, slow_first=False, g2p_fanout_max=0.25, p2g_run=4)
    assert not h.split(1)


def test_solo_reach_is_four_cells_plus_twice_the_travel_plus_the_slack():
    """update_solo asks for the particles with no other fragment within 4Δx + 2·travel + slack·Δx; past
    six cells of 2Δx (12Δx) nobody is solo. Two fragments 16Δx apart: solo at travel 0 (reach 4Δx) and at
    a reach of exactly 12Δx, not at 12.5Δx."""
    dx = 0.125  # binary-exact reaches
    x = torch.tensor([[0.5, 0.5, 0.5], [2.5, 0.5, 0.5]])
    g = types.SimpleNamespace(dx=dx, origin=(0.0, 0.0, 0.0), shape=(32, 16, 16))
    seen = []
    host = Host(Particles(x, torch.tensor([0, 1], dtype=torch.int32)), g, use_graphs=False)
    h = SlotStorage(host)
    h.set_solo = lambda mask: seen.append(None if mask is None else mask.tolist())
    h.update_solo(0.0, 1)
    h.update_solo((12 - 4 - 1) * dx / 2, 1)
    h.update_solo((12.5 - 4 - 1) * dx / 2, 1)
    assert seen[0] == [1, 1] and seen[1] is not None and seen[2] is None
