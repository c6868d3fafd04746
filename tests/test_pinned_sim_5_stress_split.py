"""The stress provider's first latch splits disconnected pieces (`StressProvider._latch`, `split_components`).

A plane cut labels particles by side; a side made of separate pieces is then, with `topology.split_components`
(the default), one fragment per connected piece: the largest piece keeps the side's id, the others take the next
free ids, and the one event lists them among its children (its parents are the sides they came from). Without
it the cut leaves exactly two fragments. The stress evaluation is replaced by a given mask and directions (no
solver runs): two bars 1 m apart, every particle over-stressed along x, so the plane is x = 0 through both.
"""

from __future__ import annotations

import types

import torch

from fracture_gs.config import TopologyConfig
from fracture_gs.sim.providers.stress import StressProvider

DX = 0.125


def _bars():
    """Two bars along x, 1 m apart along y: 10 × 2 × 2 particles each, Δx/2 apart, x = ±1/32 … ±9/32 (no
    particle on the plane x = 0, and their mean x is exactly 0)."""
    ax = (torch.arange(10, dtype=torch.float32) + 0.5) * DX / 2 - 5 * DX / 2
    ay = torch.arange(2, dtype=torch.float32) * DX / 2
    bar = torch.stack(torch.meshgrid(ax, ay, ay, indexing="ij"), -1).reshape(-1, 3)
    return torch.cat([bar, bar + torch.tensor([0.0, 1.0, 0.0])])


def _latch(split: bool, release: str = "first"):
    x = _bars()
    cfg = TopologyConfig(
        provider="stress",
        min_particles=8,
        persist_frames=1,
        max_events=1,
        split_components=split,
        min_fragment_particles=8,
        release=release,
    )
    p = StressProvider(cfg)
    d = torch.zeros(len(x), 3, dtype=torch.float64)
    d[:, 0] = 1.0
    p.over_stressed = lambda sim: (torch.ones(len(x), dtype=torch.bool), d, torch.tensor(2.0, dtype=torch.float64))
    sim = types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=DX),
        cfg=types.SimpleNamespace(max_fragments=16),
        frame=3,
        time=0.03,
    )
    return x, p(sim), p


def test_with_split_components_each_half_bar_is_its_own_fragment():
    """Four fragments 0 … 3, one per half-bar: the halves at x < 0 carry 0 and a new id, those at x > 0 carry 1 and
    the other new id; one event, latched at the frame, whose children are 0, 1, 2, 3 and whose parents are the two
    sides; the band release of the first event (release = "first")."""
    x, t, p = _latch(split=True)
    assert t is not None and p.events == 1 and len(t.events) == 1
    frag = t.fragment.long()
    assert sorted(frag.unique().tolist()) == [0, 1, 2, 3]
    ids = {}
    for bar in (0, 1):
        for side in (0, 1):
            mine = ((x[:, 1] > 0.5) == bool(bar)) & ((x[:, 0] > 0) == bool(side))
            assert int(mine.sum()) == 20 and frag[mine].unique().numel() == 1, (bar, side)
            ids[bar, side] = int(frag[mine][0])
    assert sorted([ids[0, 0], ids[1, 0]]) == [0, 2] and sorted([ids[0, 1], ids[1, 1]]) == [1, 3]
    event = t.events[0]
    assert sorted(event.children) == [0, 1, 2, 3] and {0, 1} <= set(event.parents)
    assert t.latch_frame == 3 and p.latch_frame == 3 and t.release_events == 1
    assert t.normal == (1.0, 0.0, 0.0)


def test_without_split_components_the_cut_leaves_two_fragments_by_side():
    """split_components = False: fragment 0 for every particle at x < 0 and 1 at x > 0, across both bars; one event
    with children 0 and 1."""
    x, t, _ = _latch(split=False)
    assert torch.equal(t.fragment.long(), (x[:, 0] > 0).long())
    assert len(t.events) == 1 and tuple(t.events[0].children) == (0, 1)


def test_the_release_setting_reaches_the_latched_snapshot_either_way():
    """release = "none" (bands only mark crack faces) gives release_events 0, "all" every event's, with and
    without the component split."""
    for split in (True, False):
        assert _latch(split, "none")[1].release_events == 0, split
        assert _latch(split, "all")[1].release_events == 1 << 30, split
