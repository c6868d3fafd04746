"""`sim/slot_storage.py` host decisions, on a stand-in simulator: the solo flags and launch order, the
fan-out capacity (the next power of two of the particles that are not solo, at least 256, at most all
of them; none when nobody needs it), when the fan-out and P2G's runs are used, and the solo reach."""

import types

import torch

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.slots import SlotStorage


def _host(n, fanout=True, slow_first=True, multifield=True, fanout_max=0.25, run=4):
    ensure_warp()  # set_solo wraps the slot cache for Warp
    h = types.SimpleNamespace(
        particles=[0] * n,
        solo=torch.zeros(n, dtype=torch.int32),
        _order=torch.zeros(n, dtype=torch.int64),
        _first=torch.zeros(1, dtype=torch.int64),
        fanout=fanout,
        slow_first=slow_first,
        multifield=multifield,
        _slot_cache=torch.empty(1, dtype=torch.int32),
        wp={},
        device="cpu",
        _slow=0,
        _fan_cap=0,
        g2p_fanout_max=fanout_max,
        p2g_run=run,
    )
    return h


def _mask(n, slow):
    """Solo flags with the particles listed in `slow` not solo."""
    m = torch.ones(n, dtype=torch.int32)
    m[list(slow)] = 0
    return m


def test_launch_order_lists_the_particles_that_are_not_solo_first():
    """set_solo: the order holds the particles that are not solo first (in index order), then the solo
    ones, and `_first` counts the former, with slow_first or fanout on."""
    h = _host(8)
    SlotStorage.set_solo(h, _mask(8, [5, 1, 6]))
    assert h._order.tolist() == [1, 5, 6, 0, 2, 3, 4, 7]
    assert int(h._first) == 3 and h._slow == 3
    for fanout, slow_first in ((False, True), (True, False)):  # either one needs the order
        h = _host(8, fanout=fanout, slow_first=slow_first)
        SlotStorage.set_solo(h, _mask(8, [7, 2]))
        assert h._order.tolist()[:2] == [2, 7] and int(h._first) == 2


def test_fanout_capacity_is_the_next_power_of_two_of_the_slow_particles():
    """Fan-out capacity: the next power of two ≥ the particles that are not solo, at least 256 and at most
    every particle; the slot cache holds 27 entries per fan-out slot."""
    for n, slow, cap in ((5000, 300, 512), (5000, 10, 256), (5000, 256, 256), (5000, 257, 512), (3000, 2500, 3000)):
        h = _host(n)
        SlotStorage.set_solo(h, _mask(n, range(slow)))
        assert h._fan_cap == cap, (n, slow)
        assert h._slot_cache.numel() == 27 * cap


def test_no_fanout_when_every_particle_is_solo_or_the_flags_are_cleared():
    """Nobody to fan out (every particle solo), the flags cleared (None: every particle takes the slot path,
    but the fan-out waits for the next frame's flags), or a single-field grid: capacity 0, no fan-out
    launch, a one-entry slot cache."""
    h = _host(1000)
    SlotStorage.set_solo(h, torch.ones(1000, dtype=torch.int32))
    assert h._fan_cap == 0 and h._slow == 0 and h._slot_cache.numel() == 1
    assert not SlotStorage._fans_out(h, 1, -1)
    h = _host(1000)
    SlotStorage.set_solo(h, None)
    assert h._fan_cap == 0 and h._slow == 1000 and int(h.solo.sum()) == 0
    h = _host(1000, multifield=False)
    SlotStorage.set_solo(h, _mask(1000, range(10)))
    assert h._fan_cap == 0


def test_fanout_runs_only_on_multifield_grids_outside_the_fragment_pass_and_for_few_particles_in_g2p():
    """_fans_out: multi-field, all fragments (only_fragment < 0), a fan-out capacity; in G2P also at most
    g2p_fanout_max of the particles not solo (exactly that fraction still fans out)."""
    h = _host(1000, fanout_max=0.25)
    SlotStorage.set_solo(h, _mask(1000, range(250)))
    assert SlotStorage._fans_out(h, 1, -1) and SlotStorage._fans_out(h, 1, -1, gather=True)
    assert not SlotStorage._fans_out(h, 0, -1)
    assert not SlotStorage._fans_out(h, 1, 0)
    SlotStorage.set_solo(h, _mask(1000, range(251)))
    assert SlotStorage._fans_out(h, 1, -1) and not SlotStorage._fans_out(h, 1, -1, gather=True)
    h.fanout = False
    assert not SlotStorage._fans_out(h, 1, -1)


def test_p2g_runs_stop_when_more_than_half_take_the_slot_path():
    """P2G's run length is p2g_run on a single-field grid or while at most half the particles are not solo,
    0 (one particle per thread) beyond half; G2P splits the launch only with slow_first on a multi-field
    grid."""
    h = _host(1000, run=4)
    h._slow = 500
    assert SlotStorage._run_length(h, 1) == 4
    h._slow = 501
    assert SlotStorage._run_length(h, 1) == 0 and SlotStorage._run_length(h, 0) == 4
    assert SlotStorage._split(h, 1) and not SlotStorage._split(h, 0)
    h.slow_first = False
    assert not SlotStorage._split(h, 1)


def test_solo_reach_is_four_cells_plus_twice_the_travel_plus_the_slack():
    """_update_solo asks for the particles with no other fragment within 4Δx + 2·travel + slack·Δx; past
    six cells of 2Δx (12Δx) nobody is solo. Two fragments 16Δx apart: solo at travel 0 (reach 4Δx) and at
    a reach of exactly 12Δx, not at 12.5Δx."""
    dx = 0.125  # binary-exact reaches
    x = torch.tensor([[0.5, 0.5, 0.5], [2.5, 0.5, 0.5]])
    P = types.SimpleNamespace(x=x, fragment=torch.tensor([0, 1], dtype=torch.int32))
    g = types.SimpleNamespace(dx=dx, origin=(0.0, 0.0, 0.0), shape=(32, 16, 16))
    seen = []
    h = types.SimpleNamespace(particles=P, grid=g, box_slack=1, use_graphs=False)
    h.set_solo = lambda mask: seen.append(None if mask is None else mask.tolist())
    SlotStorage._update_solo(h, 0.0)
    SlotStorage._update_solo(h, (12 - 4 - 1) * dx / 2)
    SlotStorage._update_solo(h, (12.5 - 4 - 1) * dx / 2)
    assert seen[0] == [1, 1] and seen[1] is not None and seen[2] is None
