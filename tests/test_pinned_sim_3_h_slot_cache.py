"""`sim/grid/slots.py` fan-out sizing on a stand-in simulator (`SlotStorage.set_solo` reads a few attributes):
a single particle that is not solo still gets a fan-out (capacity 256, the floor), and P2G's slot cache is
allocated anew only when its size changes (27 entries per fan-out slot, one spare entry without fan-out): a
recorded CUDA graph holds the cache's address, so a cache that moved every frame would make every frame record
its graphs again."""

import types

import torch

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.slots import SlotStorage
from fracture_gs.sim.options import SimOptions


class _Host:
    """The simulator attributes the slot storage's fan-out sizing reads."""

    def __init__(self, n):
        self.particles, self.multifield, self.device = [0] * n, True, "cpu"
        self.grid = types.SimpleNamespace(shape=(8, 8, 8))
        self.options = SimOptions(fanout=True, slow_first=True, g2p_fanout_max=0.25, p2g_run=4)


def _host(n):
    ensure_warp()  # set_solo wraps the slot cache for Warp
    host = _Host(n)
    return SlotStorage(host), host


def _mask(n, slow):
    m = torch.ones(n, dtype=torch.int32)
    m[list(slow)] = 0
    return m


def test_one_particle_that_is_not_solo_gets_the_smallest_fan_out():
    """One particle not solo (of 1000): capacity 256 (the floor), a 27 · 256-entry slot cache, and the fan-out
    runs (in P2G and, being one particle, in G2P too); none not solo: capacity 0."""
    h, _host_sim = _host(1000)
    h.set_solo(_mask(1000, [417]))
    assert h.slow == 1 and h.fan_cap == 256 and h.slot_cache.numel() == 27 * 256
    assert h.fans_out(1, -1) and h.fans_out(1, -1, gather=True)
    assert h.order.tolist()[0] == 417
    h.set_solo(_mask(1000, []))
    assert h.slow == 0 and h.fan_cap == 0 and h.slot_cache.numel() == 1
    assert not h.fans_out(1, -1)


def test_the_slot_cache_moves_only_when_its_size_changes():
    """Frames with the same capacity keep the very same cache tensor (and Warp array): every particle solo
    twice (the one-entry cache), then 300 and 400 particles not solo (both capacity 512) keep one cache; 600
    (capacity 1024) allocates a new one, and going back to nobody not solo allocates the one-entry cache."""
    h, _host_sim = _host(5000)
    first, first_view = h.slot_cache, h.wp["slot_cache"]
    h.set_solo(torch.ones(5000, dtype=torch.int32))
    assert h.slot_cache is first and h.wp["slot_cache"] is first_view  # already the right size: nothing rewrapped
    h.set_solo(torch.ones(5000, dtype=torch.int32))
    assert h.slot_cache is first
    h.set_solo(_mask(5000, range(300)))
    cache, view = h.slot_cache, h.wp["slot_cache"]
    assert cache.numel() == 27 * 512 and cache is not first
    h.set_solo(_mask(5000, range(400)))
    assert h.slot_cache is cache and h.wp["slot_cache"] is view
    h.set_solo(_mask(5000, range(600)))
    assert h.slot_cache.numel() == 27 * 1024 and h.slot_cache is not cache
    h.set_solo(torch.ones(5000, dtype=torch.int32))
    assert h.slot_cache.numel() == 1
    one = h.slot_cache
    h.set_solo(None)  # flags cleared: still no fan-out, the same one-entry cache
    assert h.fan_cap == 0 and h.slot_cache is one
