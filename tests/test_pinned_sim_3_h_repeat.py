"""`sim/providers/stress.py`'s repeated fracture (`StressProvider._repeat`), with the stress evaluation replaced by
a given mask (no solver runs): after the first latch, a fragment is cut again once at least `min_particles` of
its particles outside the band are over-stressed on `persist_frames` consecutive evaluations (a frame below the
count starts the streak over); the cut plane goes through those particles, only that fragment's positive side
takes a new id, and the new band carries the event's 1-based index (the second event tags 2). With fewer events
left than fragments due, the most over-stressed fragment goes first."""

import types

import torch

from fracture_gs.config import TopologyConfig
from fracture_gs.sim.providers.stress import StressProvider
from fracture_gs.sim.topology import Topology

DX = 0.125


def _blob(centre, n_side=4):
    """n_side³ particles Δx/2 apart around `centre`: offsets ±Δx/4, ±3Δx/4 along each axis for n_side = 4."""
    a = (torch.arange(n_side, dtype=torch.float32) - (n_side - 1) / 2) * DX / 2
    g = torch.stack(torch.meshgrid(a, a, a, indexing="ij"), -1).reshape(-1, 3)
    return g + torch.tensor(centre)


def _latched(persist=2, max_events=3, min_particles=8):
    """Blob A (fragment 0, particles 0-63) and blob B (fragment 1, 64-127) after a first cut at x = 2 (no band:
    the blobs are far from it); a provider holding that topology, and a stand-in simulator."""
    x = torch.cat([_blob((1.0, 1.0, 1.0)), _blob((3.0, 1.0, 1.0))])
    t = Topology.from_plane(x, (2.0, 1.0, 1.0), (1.0, 0.0, 0.0), DX)
    cfg = TopologyConfig(
        provider="stress",
        min_particles=min_particles,
        persist_frames=persist,
        max_events=max_events,
        band_width=0.5,  # |distance| < Δx/2: the two layers of a blob nearest the cut
        split_components=False,
    )
    p = StressProvider(cfg)
    p.topology, p.events = t, 1
    p.mask = torch.zeros(len(x), dtype=torch.bool)
    d = torch.zeros(len(x), 3, dtype=torch.float64)
    d[:, 0] = 1.0
    p.over_stressed = lambda sim: (p.mask, d, torch.tensor(2.0, dtype=torch.float64))
    P = types.SimpleNamespace(x=x, fragment=t.fragment.clone(), band=t.band.clone())
    sim = types.SimpleNamespace(
        particles=P, grid=types.SimpleNamespace(dx=DX), cfg=types.SimpleNamespace(max_fragments=16), frame=0, time=0.0
    )
    return p, sim


def _step(p, sim, over):
    """One evaluation on the next frame with the particles listed in `over` over-stressed; a returned topology
    is latched (the stand-in's labels follow it)."""
    sim.frame += 1
    sim.time = 0.01 * sim.frame
    p.mask[:] = False
    p.mask[list(over)] = True
    t = p(sim)
    if t is not None:
        sim.particles.fragment, sim.particles.band = t.fragment.clone(), t.band.clone()
    return t


def test_a_fragment_is_cut_again_after_persisting_and_its_band_is_tagged_with_the_event():
    """All of blob B over-stressed: the first evaluation starts the streak (nothing yet), the second cuts B by
    the plane through its centroid x = 3 along x: B's particles with x > 3 take id 2, blob A keeps 0, the band
    is B's two middle layers (|x − 3| = Δx/4 < Δx/2), tagged 2 (the second event), and the streaks start over."""
    p, sim = _latched()
    B = range(64, 128)
    assert _step(p, sim, B) is None and p.fragment_streak[1] == 1 and p.fragment_streak[0] == 0
    t = _step(p, sim, B)
    assert t is not None and p.events == 2 and len(t.events) == 2 and p.topology is t
    e = t.events[1]
    assert (e.parents, e.children, e.frame) == ((1,), (2,), 2)
    assert torch.allclose(torch.tensor(e.point), torch.tensor([3.0, 1.0, 1.0]), atol=1e-6)
    x = sim.particles.x
    want_fragment = torch.where(x[:, 0] > 3.0, 2, torch.where(x[:, 0] > 2.0, 1, 0)).to(torch.int32)
    assert torch.equal(t.fragment, want_fragment)
    want_band = torch.where((x[:, 0] - 3.0).abs() < 0.5 * DX, 2, 0).to(torch.int32)
    assert torch.equal(t.band, want_band) and int((t.band == 2).sum()) == 32
    assert p.fragment_streak == {}


def test_the_streak_needs_min_particles_on_consecutive_evaluations():
    """min_particles = 8, persist 2: 8 over-stressed (exactly enough), then 7 (the streak starts over), then 8
    and 8 again: the cut comes on the fourth evaluation, not before."""
    p, sim = _latched()
    eight, seven = range(80, 88), range(80, 87)  # in the layer at x = 3 − Δx/4: the plane has B on both sides
    assert _step(p, sim, eight) is None and p.fragment_streak[1] == 1
    assert _step(p, sim, seven) is None and p.fragment_streak[1] == 0
    assert _step(p, sim, eight) is None and p.fragment_streak[1] == 1
    assert _step(p, sim, eight) is not None and p.events == 2


def test_band_particles_do_not_count_and_the_most_over_stressed_fragment_goes_first():
    """Over-stressed particles inside a band are released and not counted: with all of A's 64 in a band, A is
    never due. Outside the band, A with 20 and B with 30 over-stressed and one event left (max_events 2): B is
    cut, A is not, and no further event follows."""
    p, sim = _latched(persist=1, max_events=2)
    sim.particles.band[:64] = 1
    p.topology.band[:64] = 1
    assert _step(p, sim, range(64)) is None and p.fragment_streak[0] == 0
    sim.particles.band[:64] = 0
    p.topology.band[:64] = 0
    t = _step(p, sim, list(range(20)) + list(range(64, 94)))
    assert t is not None and t.events[1].parents == (1,) and int(t.fragment[:64].max()) == 0
    assert _step(p, sim, range(128)) is None and p.events == 2
