"""`sim/providers/voronoi.py`: where the shatter's cell sites fall (a Gaussian of standard deviation
`impact_radius` around the impact), that every requested cell gets a site, the event's bookkeeping, and
when the provider latches. Unit-level: the provider reads only a few attributes of the simulator, given
here by a stand-in."""

import types

import torch

from fracture_gs.config import PlaneBoundary, TopologyConfig
from fracture_gs.sim.providers.cuts import voronoi_labels
from fracture_gs.sim.providers.voronoi import VoronoiProvider, voronoi_sites


def _line(n=2001, half=1.0):
    """Particles on the x axis from −half to +half [m] ([n, 3] float32)."""
    x = torch.zeros(n, 3)
    x[:, 0] = torch.linspace(-half, half, n)
    return x


def _sim(x, dx=0.05, max_fragments=64, frame=0, time=0.0, boundaries=()):
    return types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=dx),
        cfg=types.SimpleNamespace(max_fragments=max_fragments, boundaries=list(boundaries)),
        frame=frame,
        time=time,
        device="cpu",
    )


def test_impact_sites_follow_a_gaussian_of_standard_deviation_impact_radius():
    """One site drawn around an impact at a particle lands at squared distance r² with probability
    ∝ exp(−r²/2σ²), σ = impact_radius: over 3000 seeds the mean r² matches that distribution's mean on
    the particles (≈ σ² on a line) within 8 %."""
    x, sigma = _line(), 0.05
    r2 = x[:, 0].double() ** 2
    w = torch.exp(-r2 / (2 * sigma**2))
    want = float((w * r2).sum() / w.sum())
    assert abs(want - sigma**2) < 0.01 * sigma**2  # the line resolves the Gaussian
    got = [float(voronoi_sites(x, 1, seed, (0.0, 0.0, 0.0), sigma)[0, 0]) ** 2 for seed in range(3000)]
    mean = sum(got) / len(got)
    assert abs(mean - want) < 0.08 * want, (mean, want)


def test_every_requested_cell_gets_a_distinct_site_even_where_the_impact_kernel_underflows():
    """With an impact radius so small that exp(−r²/2σ²) is 0 for all but a handful of particles, asking
    for 20 cells still gives 20 distinct particles (far particles keep a tiny positive weight), and the
    particle at the impact is one of them."""
    x = _line(201)
    sites = voronoi_sites(x, 20, 0, (0.0, 0.0, 0.0), 1e-3)
    assert sites.shape == (20, 3)
    assert len(torch.unique(sites[:, 0])) == 20
    assert bool((sites[:, 0].abs() < 1e-6).any())


def test_impact_point_off_the_object_draws_sites_nearest_to_it():
    """The kernel is measured from the particle nearest to the impact: an impact point 10 m away (100 σ,
    where every absolute weight would underflow) still puts a single site on the nearest particle."""
    x = _line(201)
    for seed in range(5):
        site = voronoi_sites(x, 1, seed, (11.0, 0.0, 0.0), 0.1)
        assert float(site[0, 0]) == 1.0


def test_uniform_sites_are_distinct_particles_reproducible_by_seed():
    """Without an impact point the sites are `cells` distinct particles, the same for the same seed."""
    x = _line(101)
    a, b = voronoi_sites(x, 7, 3), voronoi_sites(x, 7, 3)
    assert torch.equal(a, b) and len(torch.unique(a[:, 0])) == 7
    assert not torch.equal(a, voronoi_sites(x, 7, 4))


def _block(n=6):
    g = torch.linspace(0.0, 0.5, n)
    return torch.stack(torch.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)


def test_voronoi_event_lists_every_cell_as_a_child_and_caps_cells_at_max_fragments():
    """The shatter event's children are the ids 0 … K−1 of every cell (K = cells, but no more than
    sim.max_fragments), and the labels are the nearest site's cell."""
    x = _block()
    cfg = TopologyConfig(provider="voronoi", cells=6, seed=1, split_components=False, band_width=0.5)
    topo = VoronoiProvider(cfg)(_sim(x))
    assert topo.events[0].children == tuple(range(6))
    assert int(topo.fragment.max()) == 5
    p = VoronoiProvider(cfg)
    p(_sim(x))
    fragment, band = voronoi_labels(x, p.sites, 0.5 * 0.05)
    assert torch.equal(topo.fragment, fragment) and torch.equal(topo.band, band)
    capped = VoronoiProvider(TopologyConfig(provider="voronoi", cells=10, seed=1, split_components=False))
    topo = capped(_sim(x, max_fragments=4))
    assert capped.sites.shape[0] == 4 and topo.events[0].children == (0, 1, 2, 3)


def test_voronoi_latches_once_at_its_frame_or_time():
    """It latches at the first frame end at or after `latch_frame` (or `latch_time`, within float
    rounding), never before, and only once."""
    x = _block(4)
    p = VoronoiProvider(TopologyConfig(provider="voronoi", cells=3, latch_frame=2, split_components=False))
    assert p(_sim(x, frame=1)) is None
    assert p(_sim(x, frame=2)) is not None
    assert p(_sim(x, frame=3)) is None
    t = TopologyConfig(provider="voronoi", cells=3, latch_time=0.3, split_components=False)
    assert not VoronoiProvider(t).due(_sim(x, time=0.3 - 1e-6))
    assert VoronoiProvider(t).due(_sim(x, time=0.1 + 0.2 - 1e-12))


def test_voronoi_on_contact_latches_within_one_cell_of_a_plane():
    """`latch_on_contact`: due once a particle is closer than Δx to a plane collider (the plane's normal
    taken as a direction, whatever its length), not before."""
    dx = 0.05
    cfg = TopologyConfig(provider="voronoi", cells=3, latch_on_contact=True, split_components=False)
    floor = PlaneBoundary(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 2.0))
    for gap, due in ((0.9 * dx, True), (1.1 * dx, False)):
        x = _block(4) + torch.tensor([0.0, 0.0, gap])
        assert VoronoiProvider(cfg).due(_sim(x, dx=dx, boundaries=[floor])) is due
    assert not VoronoiProvider(cfg).due(_sim(_block(4), dx=dx))  # no plane, no contact
