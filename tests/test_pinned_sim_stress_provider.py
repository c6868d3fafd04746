"""`sim/providers/stress.py`'s decision once particles are over-stressed (the stress evaluation itself is
replaced by a given mask and directions, so the test runs no solver): a single crack latches the plane
through the centroid of every over-stressed particle whatever `max_events` allows, several separate
cracks are cut one by one, largest first, and the streak counts consecutive frames only."""

import types

import torch

from fracture_gs.config import TopologyConfig
from fracture_gs.sim.providers.stress import StressProvider, over_stressed_clusters

DX = 0.125


def _blob(centre, n_side):
    """n_side³ particles half a cell apart around `centre` (one connected group on cells of Δx)."""
    a = (torch.arange(n_side, dtype=torch.float32) - (n_side - 1) / 2) * DX / 2
    g = torch.stack(torch.meshgrid(a, a, a, indexing="ij"), -1).reshape(-1, 3)
    return g + torch.tensor(centre)


def _provider(x, over, max_events, min_particles=8):
    cfg = TopologyConfig(
        provider="stress", min_particles=min_particles, persist_frames=1, max_events=max_events, split_components=False
    )
    p = StressProvider(cfg)
    d = torch.zeros(len(x), 3, dtype=torch.float64)
    d[:, 0] = 1.0  # every principal direction along x
    p.over_stressed = lambda sim: (over, d, torch.tensor(2.0, dtype=torch.float64))
    return p


def _sim(x, frame=0):
    return types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=DX),
        cfg=types.SimpleNamespace(max_fragments=16),
        frame=frame,
        time=0.01 * frame,
    )


def test_one_crack_latches_through_every_over_stressed_particle_whatever_max_events():
    """A cluster of 27 over-stressed particles plus 3 stray ones far away (each too small to be a crack of
    its own): the latched plane goes through the centroid of all 30, the same with max_events = 1 and 4 —
    allowing more events does not change the first cut."""
    cluster = _blob((1.0, 1.0, 1.0), 3)
    strays = torch.tensor([[3.0, 1.0, 1.0], [1.0, 3.0, 1.0], [3.0, 3.0, 3.0]])
    calm = _blob((2.0, 2.0, 1.0), 2)
    x = torch.cat([cluster, strays, calm])
    over = torch.zeros(len(x), dtype=torch.bool)
    over[:30] = True
    want = x[:30].double().mean(0)
    for max_events in (1, 4):
        p = _provider(x, over, max_events)
        t = p(_sim(x))
        assert t is not None and p.events == 1 and len(t.events) == 1
        assert torch.allclose(torch.tensor(t.point, dtype=torch.float64), want, atol=1e-9), max_events
        assert t.normal == (1.0, 0.0, 0.0)


def test_separate_cracks_are_cut_one_by_one_largest_first():
    """Two separate over-stressed clusters (64 and 27 particles) with max_events = 2: the first cut goes
    through the larger one's centroid, a second event (band tag 2) cuts through the smaller one's; with
    max_events = 1 a single plane through all of them, and no further event on later frames."""
    big, small = _blob((1.0, 1.0, 1.0), 4), _blob((3.0, 1.0, 1.0), 3)
    x = torch.cat([big, small])
    over = torch.ones(len(x), dtype=torch.bool)
    p = _provider(x, over, 2)
    t = p(_sim(x))
    assert p.events == 2 and len(t.events) == 2 and int(t.band.max()) == 2
    assert torch.allclose(torch.tensor(t.events[0].point), big.double().mean(0).float(), atol=1e-6)
    assert torch.allclose(torch.tensor(t.events[1].point), small.double().mean(0).float(), atol=1e-6)
    assert int(t.fragment.max()) == 2
    p1 = _provider(x, over, 1)
    t1 = p1(_sim(x))
    assert len(t1.events) == 1
    assert torch.allclose(torch.tensor(t1.point), x.double().mean(0).float(), atol=1e-6)
    assert p1(_sim(x, 1)) is None and p1.topology is t1


def test_the_streak_counts_consecutive_frames_only():
    """persist_frames = 2: over-stressed on frames 3 and 5 (a gap) does not latch; on 5 and 6 it does;
    evaluating frame 5 twice counts it once. The first frame with any over-stressed particle is recorded."""
    x = _blob((1.0, 1.0, 1.0), 3)
    over = torch.ones(len(x), dtype=torch.bool)
    p = _provider(x, torch.zeros(len(x), dtype=torch.bool), 1)
    assert p(_sim(x, 1)) is None and p.first_exceed_frame is None and p.streak == 0
    p = _provider(x, over, 1)
    p.cfg.persist_frames = 2
    assert p(_sim(x, 3)) is None and p(_sim(x, 5)) is None and p.streak == 1
    assert p(_sim(x, 5)) is None and p.streak == 1
    assert p(_sim(x, 6)) is not None and p.latch_frame == 6
    assert p.first_exceed_frame == 3


def test_exactly_min_particles_over_stressed_is_enough():
    """The condition is count ≥ min_particles: 8 over-stressed particles with min_particles = 8 latch (persist
    1); 7 do not."""
    x = _blob((1.0, 1.0, 1.0), 3)
    for n, latched in ((8, True), (7, False)):
        over = torch.zeros(len(x), dtype=torch.bool)
        over[:n] = True
        assert (_provider(x, over, 1, min_particles=8)(_sim(x)) is not None) is latched


def test_two_minimal_clusters_are_two_cracks():
    """over_stressed_clusters: two separate groups of exactly min_size particles are two groups (the
    smallest case that is split), a lone group below min_size is dropped."""
    x = torch.cat([_blob((1.0, 1.0, 1.0), 2), _blob((3.0, 1.0, 1.0), 2), torch.tensor([[5.0, 5.0, 5.0]])])
    over = torch.ones(len(x), dtype=torch.bool)
    over[16] = False  # exactly 2 · min_size over-stressed
    assert [int(g.sum()) for g in over_stressed_clusters(x, over, DX, 8)] == [8, 8]
    over[16] = True  # a lone particle joins neither
    groups = over_stressed_clusters(x, over, DX, 8)
    assert [int(g.sum()) for g in groups] == [8, 8]
    assert not bool(groups[0][16]) and not bool(groups[1][16])
