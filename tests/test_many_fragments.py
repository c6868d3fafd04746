"""Many fragments (beyond the paper's L1–L2): K fields in sparse node slots, overflow accounting,
pairwise momentum-conserving contact with Coulomb friction and mass-gradient normals, repeated
impulse-free latches, connected components and the Voronoi shatter."""

import math

import pytest
import torch
from simutil import block, config, fill_slots, particles, rand_rotations, rel_err

from fracture_gs import sim as S
from fracture_gs.config import OraclePlane
from fracture_gs.sim import reference as ref
from fracture_gs.sim.providers.cuts import plane_cut, split_components, voronoi_labels
from fracture_gs.sim.providers.voronoi import voronoi_sites
from fracture_gs.sim.storage import COUNT_SLOT_OVERFLOW
from fracture_gs.sim.topology import load_history, save_history

STATE = ("x", "v", "C", "F", "mass", "volume")


def voronoi_state(seed, device, cells=5, slots=8, n=3000, variant="full", storage="slots"):
    """Random particles in a box cut into `cells` Voronoi pieces (fragments share many nodes), in the slot
    storage by default (these tests read its slots; tests/test_box_storage.py covers the boxes)."""
    g = torch.Generator().manual_seed(seed)
    x = 0.3 + 0.4 * torch.rand(n, 3, generator=g)
    U, V = rand_rotations(n, g), rand_rotations(n, g)
    s = 0.8 + 0.4 * torch.rand(n, 3, generator=g, dtype=torch.float64)
    P = S.Particles(
        x=x,
        v=torch.randn(n, 3, generator=g),
        C=torch.randn(n, 3, 3, generator=g),
        F=(U @ torch.diag_embed(s) @ V.transpose(1, 2)).float(),
        mass=0.5 + torch.rand(n, generator=g),
        volume=torch.full((n,), 1e-5),
        E=1e4,
        nu=0.3,
    )
    cfg = config(32, variant=variant, gravity=(0.0, 0.0, -9.8), dt=1e-3, field_slots=slots, grid_storage=storage)
    sim = S.Simulator(cfg, P, device=device)
    sites = voronoi_sites(sim.particles.x, cells, seed)
    fragment, band = voronoi_labels(sim.particles.x, sites, 2.0 / 32)
    topo = S.Topology(fragment=fragment, band=band, normal=(1.0, 0.0, 0.0), point=(0.5, 0.5, 0.5))
    return sim, topo


@pytest.mark.slow
@pytest.mark.parametrize("normal", ["latched", "mass_gradient"])
def test_k_field_transfer_matches_reference(device, seed, normal):
    """With K = 5 fragments and enough slots, P2G (mass, momentum, band mass) and G2P without contact
    equal the dense float64 K-field reference; no slot overflows, per-fragment mass exact. The band mass
    is kept only where the contact gate reads it (latched normals); with mass-gradient normals the grid
    holds none and everything else is the same."""
    sim, topo = voronoi_state(seed, device, variant="local_multifield")
    sim.cfg.contact.normal = normal
    sim.latch(topo)
    P, g, dt = sim.particles, sim.grid, 1e-3
    sim.cfg.wall_cells = 0
    sim.compute_stress(sim.stress, commit=True)
    K = sim.n_fragments
    assert K == 5
    x0, F0, field = P.x.cpu().clone(), P.F.cpu().clone(), P.fragment.cpu().long()
    gm, gp, gb = ref.p2g(
        x0,
        P.v.cpu(),
        P.C.cpu(),
        P.mass.cpu(),
        P.volume.cpu(),
        sim.stress.cpu(),
        field,
        K,
        g.shape,
        g.origin,
        g.dx,
        dt,
        band=P.band.cpu(),
    )
    sim.p2g(dt)
    assert int(((gm > 0).sum(0) >= 3).sum()) > 0, "some nodes must hold three or more fragments"
    if normal == "mass_gradient":
        assert float(gb.abs().max()) > 0 and not bool(g.band_mass.any()), "no band mass kept: nothing reads it"
        gb = torch.zeros_like(gb)
    for name, ours, theirs in (("mass", g.mass, gm), ("momentum", g.momentum, gp), ("band mass", g.band_mass, gb)):
        assert rel_err(ours.cpu(), theirs) <= 1e-5, f"K-field P2G {name} (seed {seed})"
    assert int(sim.counts[COUNT_SLOT_OVERFLOW]) == 0
    sim.update_grid(dt)
    gv = ref.grid_update(gm, gp, gb, sim.eps_m, sim.eps_b, dt, sim.cfg.gravity)
    assert rel_err(g.velocity.cpu(), gv) <= 1e-5, f"K-field grid update (seed {seed})"
    sim.g2p(dt)
    x1, v1, C1, F1 = ref.g2p(x0, F0, g.velocity.cpu().double(), field, g.origin, g.dx, dt)
    for name, ours, theirs in (("x", P.x, x1), ("v", P.v, v1), ("C", P.C, C1), ("F", P.F, F1)):
        assert rel_err(ours.cpu(), theirs) <= 1e-5, f"K-field G2P {name} (seed {seed})"


def test_claimed_slots_take_the_dense_path(device, seed):
    """A particle whose 27 stencil nodes all hold its own fragment in slot 0 (claimed earlier in the
    frame) deposits with the unrolled dense stencil and no slot lookups. With five Voronoi pieces many
    non-band particles qualify once the first P2G has claimed the slots, and the second P2G of the same
    state gives the same fields as the first, which went through the claims (CPU: bitwise; CUDA: to the
    float32 atomics' order); the following G2P matches the float64 reference."""
    sim, topo = voronoi_state(seed, device, variant="local_multifield")
    sim.latch(topo)
    sim.cfg.wall_cells = 0
    P, g, dt = sim.particles, sim.grid, 1e-3
    sim.compute_stress(sim.stress, commit=True)
    sim.p2g(dt)  # claims: owner words, pool rows and pool slots (they last the frame)
    first = g._mp.clone()
    base = torch.floor((P.x.cpu().double() - torch.tensor(g.origin, dtype=torch.float64)) / g.dx - 0.5).long()
    offsets = torch.stack(torch.meshgrid(*[torch.arange(3)] * 3, indexing="ij"), -1).reshape(27, 3)
    nodes = base[:, None, :] + offsets[None]  # [N, 27, 3]
    X, Y, Z = g.shape
    owner = g._owner.cpu().long()[(nodes[..., 0] * Y + nodes[..., 1]) * Z + nodes[..., 2]] & S.layout.OWNER_MASK
    owned = (owner == P.fragment.cpu().long()[:, None] + 1).all(1) & (P.band.cpu() == 0)
    # 120 seeds gave 0.21-0.43 (one run under coverage 0.16): the premise is that a good share qualifies, not a number
    share = float(owned.float().mean())
    assert share > 0.1, f"particles away from the cuts own every node of their stencil: {share:.3f} (seed {seed})"
    sim.p2g(dt)
    if device == "cpu":
        assert torch.equal(g._mp, first)
    else:
        torch.testing.assert_close(g._mp, first, rtol=1e-5, atol=1e-6 * float(first.abs().max()))
    x0, F0, field = P.x.cpu().clone(), P.F.cpu().clone(), P.fragment.cpu().long()
    sim.update_grid(dt)
    sim.g2p(dt)
    x1, v1, C1, F1 = ref.g2p(x0, F0, g.velocity.cpu().double(), field, g.origin, g.dx, dt)
    for name, ours, theirs in (("x", P.x, x1), ("v", P.v, v1), ("C", P.C, C1), ("F", P.F, F1)):
        assert rel_err(ours.cpu(), theirs) <= 1e-5, f"G2P {name} (seed {seed})"


@pytest.mark.parametrize("slots", [2, 4, 8])
def test_field_sums_match_their_torch_twins(device, seed, slots):
    """The per-frame diagnostics' two launches (`Grid.field_sums`: per-fragment grid mass, counterfactual
    mixing, shared support) equal the torch reductions `Grid.fragment_mass` and `Grid.mixing` of the
    same K-field grid (five Voronoi pieces, with and without slot overflows) to float64 rounding."""
    sim, topo = voronoi_state(seed, device, slots=slots)
    sim.latch(topo)
    sim.compute_stress(sim.stress, commit=True)
    sim.p2g(1e-3)
    g, K = sim.grid, sim.n_fragments
    cf, shared, mass = g.field_sums(sim.eps_m, K)
    cf_ref, shared_ref = g.mixing(sim.eps_m)
    assert float(cf_ref) > 0 and float(shared_ref) > 0, "the state must hold shared nodes"
    torch.testing.assert_close(mass, g.fragment_mass(K), rtol=1e-12, atol=0)
    torch.testing.assert_close(cf, cf_ref, rtol=1e-10, atol=0)
    torch.testing.assert_close(shared, shared_ref, rtol=1e-12, atol=0)


def test_slot_overflow_is_counted_and_conserves_mass(device, seed):
    """Two slots for five fragments: nodes reached by a third fragment merge it into slot 0. Every
    such deposit is counted, the grid still holds all the mass and momentum of the particles, and
    the merged fragments' own fields lose exactly what slot 0 gained."""
    sim, topo = voronoi_state(seed, device, slots=2)
    sim.latch(topo)
    sim.compute_stress(sim.stress, commit=True)
    sim.p2g(1e-3)
    P, g = sim.particles, sim.grid
    assert int(sim.counts[COUNT_SLOT_OVERFLOW]) > 0, "the overflow must be counted"
    total = float(P.mass.double().sum())
    assert abs(float(g.mass.double().sum()) - total) <= 1e-6 * total, "mass is never dropped"
    per = g.fragment_mass(sim.n_fragments)
    assert abs(float(per.sum()) - total) <= 1e-6 * total
    # advancing a frame reports it to the metrics row
    tracker = sim.diagnostics_tracker()
    sim.advance(0.002)
    assert tracker.history[-1]["slot_overflow"] > 0 and sim.slot_overflow_total > 0


def contact_sim(device, slots, friction=0.0, normal="latched"):
    x, vol = block((0.4, 0.4, 0.4), (0.45, 0.45, 0.45), 0.01)
    cfg = S.SimConfig(
        dx=1 / 8,
        grid_shape=(8, 8, 8),
        gravity=(0, 0, 0),
        variant="full",
        wall_cells=0,
        field_slots=slots,
        contact=S.ContactConfig(friction=friction, normal=normal),
        grid_storage="slots",  # the test writes fields into the slots
    )
    sim = S.Simulator(cfg, particles(x, vol), device=device)
    sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (0.6, 0.0, 0.8), 0.0))
    sim.grid.ensure_pool(sim.grid.n_nodes)
    return sim


@pytest.mark.parametrize("K, friction, normal", [(4, 0.0, "latched"), (4, 0.5, "mass_gradient"), (3, 0.2, "latched")])
def test_k_field_contact_conserves_momentum(device, seed, K, friction, normal):
    """At nodes holding K random fields (K ≤ field_slots): every pair of approaching fields in contact
    gets an equal and opposite impulse, so node momentum Σ_k m_k v_k is conserved (relative residual
    ≤ 1e-6); the result equals the float64 pairwise reference (latched normal, or normals from the
    fields' nodal mass gradients by central differences); with friction 0 and one normal the
    tangential velocity of every field is untouched; nodes whose fields all separate get no impulse."""
    g = torch.Generator().manual_seed(seed)
    shape = (8, 8, 8)
    m = 0.1 + torch.rand(K, *shape, generator=g)
    v = torch.randn(K, *shape, 3, generator=g)
    sim = contact_sim(device, 4, friction, normal)
    sim.normal_mode = 1 if normal == "mass_gradient" else 0
    sim.grid.ensure_pool(2 * sim.grid.n_nodes)
    fill_slots(sim.grid, m, v)
    sim.update_grid(1e-3)
    w = sim.grid.velocity.double().cpu()
    p0 = (m[..., None].double() * v.double()).sum(0)
    p1 = (m[..., None].double() * w).sum(0)
    assert float((p1 - p0).norm(dim=-1).max() / p0.norm(dim=-1).max()) <= 1e-6, "node momentum"
    n_l = torch.tensor(sim.topology.normal, dtype=torch.float64)
    M = m[0].numel()
    vv, mm = v.reshape(K, M, 3).transpose(0, 1), m.reshape(K, M).T
    md = m.double()
    grad = torch.stack([(md.roll(-1, a + 1) - md.roll(1, a + 1)) for a in range(3)], -1)  # central differences
    for a in range(3):  # one-sided at the grid's faces (the kernel clamps the neighbour into the grid)
        lo, hi = [slice(None)] * 4, [slice(None)] * 4
        lo[a + 1], hi[a + 1] = 0, -1
        grad[tuple(lo) + (a,)] = md[tuple(lo[: a + 1] + [1])] - md[tuple(lo)]
        grad[tuple(hi) + (a,)] = md[tuple(hi)] - md[tuple(hi[: a + 1] + [-2])]
    gg = grad.reshape(K, M, 3).transpose(0, 1)
    frag = torch.arange(K).expand(M, K)

    def normals(a, b, lo, hi):
        if normal == "latched":
            return n_l.expand(M, 3)
        rows = torch.arange(M)
        return torch.nn.functional.normalize(gg[rows, hi] - gg[rows, lo], dim=1)

    fill = sim.cfg.contact.fill * sim.node_mass
    touching = (lambda a, b: mm[:, a] + mm[:, b] >= fill) if normal != "latched" else None
    expect = ref.contact_fields(vv, mm, frag, mm, sim.eps_m, sim.eps_b, normals, mu=friction, touching=touching)
    assert rel_err(w.reshape(K, M, 3).transpose(0, 1), expect) <= 1e-5, f"pairwise contact (seed {seed})"
    if normal == "latched":
        un = torch.stack([((vv[:, b] - vv[:, a]).double() @ n_l) for a in range(K) for b in range(a + 1, K)], 1)
        separating = (un >= 0).all(1)
        assert bool(separating.any()) and bool((~separating).any())
        got = w.reshape(K, M, 3).transpose(0, 1)
        assert torch.allclose(got[separating], vv[separating].double(), atol=1e-6), "separating fields got an impulse"
        if friction == 0.0:
            tan = lambda d: d - (d @ n_l)[..., None] * n_l  # noqa: E731
            assert torch.allclose(tan(got), tan(vv.double()), atol=1e-5), "frictionless contact changed v_t"


def sliding_block(device, mu, theta_deg, seconds=0.3, storage="auto", normal="auto"):
    """A block (fragment 1) resting on a slab (fragment 0) whose bottom is held by a sticky floor, under
    gravity tilted by θ along x; returns times and the block's mean x velocity."""
    dx = 1 / 32
    base, vol = block((0.1, 0.3, 0.12), (0.9, 0.7, 0.3), dx / 2)
    top, _ = block((0.35, 0.4, 0.3), (0.55, 0.6, 0.42), dx / 2)
    x = torch.cat([base, top])
    g = 9.8
    th = math.radians(theta_deg)
    floor = S.PlaneBoundary(point=(0, 0, 0.17), normal=(0, 0, 1), mode="sticky")
    cfg = S.SimConfig(
        dx=dx,
        grid_shape=(32, 32, 32),
        gravity=(g * math.sin(th), 0.0, -g * math.cos(th)),
        dt=4e-4,
        variant="full",
        boundaries=[floor],
        contact=S.ContactConfig(friction=mu, normal=normal),
        grid_storage=storage,
    )
    sim = S.Simulator(cfg, particles(x, vol, rho=1000.0, E=3e5, nu=0.3), device=device)
    # a one-particle band: the band's stress is released, and a thicker stress-free layer on the slab is
    # dragged into a ridge the block rides up on (measured: 8 % more normal force than the weight)
    sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.3), (0.0, 0.0, 1.0), 0.6 * dx))
    on_top = sim.particles.fragment == 1
    ts, vs = [], []
    for _ in range(int(round(seconds / 0.01))):
        sim.advance(0.01)
        ts.append(sim.time)
        vs.append(float(sim.particles.v[on_top, 0].mean()))
    return torch.tensor(ts), torch.tensor(vs), g, th


@pytest.mark.slow
@pytest.mark.parametrize("storage, normal", [("slots", "latched"), ("boxes", "latched")])
def test_friction_decelerates_at_mu_g_and_sticks_below_threshold(device, storage, normal):
    """Coulomb friction between fragments: on a slope steeper than the friction angle the block
    accelerates at g(sin θ − μ cos θ) within 5 %; below it (tan θ < μ) it sticks (speed ≤ 2 % of
    what a frictionless block reaches). In both grid storages, along the latched normal. (Mass-gradient
    normals, the same in both storages, make the block ride a ridge here: 2.1 m/s² against 3.2.)"""
    mu = 0.3
    t, v, g, th = sliding_block(device, mu, 35.0, storage=storage, normal=normal)
    keep = t > 0.08  # after the block has settled onto the slab
    slope = float(
        torch.linalg.lstsq(
            torch.stack([t[keep], torch.ones_like(t[keep])], 1).double(), v[keep].double()[:, None]
        ).solution[0]
    )
    expected = g * (math.sin(th) - mu * math.cos(th))
    assert slope == pytest.approx(expected, rel=0.05), (slope, expected)
    t, v, g, th = sliding_block(device, mu, 10.0, seconds=0.2, storage=storage, normal=normal)
    free = g * math.sin(th) * float(t[-1])
    late = v[len(v) // 2 :]  # once the contact pressure is established: an elastic oscillation about rest
    assert abs(float(late.mean())) <= 0.02 * free and float(late.abs().max()) <= 0.1 * free, (
        [float(a) for a in v],
        free,
    )


def test_u_cut_gives_three_pieces_and_repeated_latches_are_impulse_free(device):
    """A plane through both arms of a U leaves three connected pieces; the oracle's second timed plane
    then cuts again. Every latch leaves x, v, C, F, m, V unchanged to the bit and the history replays."""
    dx = 1 / 32
    left, vol = block((0.3, 0.4, 0.3), (0.38, 0.6, 0.7), dx / 2)
    right, _ = block((0.62, 0.4, 0.3), (0.7, 0.6, 0.7), dx / 2)
    bottom, _ = block((0.38, 0.4, 0.3), (0.62, 0.6, 0.38), dx / 2)
    x = torch.cat([left, right, bottom])
    frag, _, parents, children = plane_cut(
        x,
        torch.zeros(len(x), dtype=torch.int32),
        torch.zeros(len(x), dtype=torch.int32),
        (0.5, 0.5, 0.55),
        (0, 0, 1),
        dx,
        64,
    )
    assert (parents, children) == ([0], [1])
    frag, parents, children = split_components(x, frag, dx, 64)
    assert len(torch.unique(frag)) == 3 and children == [2], "the cut U must fall into three pieces"
    planes = [
        OraclePlane(point=(0.5, 0.5, 0.55), normal=(0, 0, 1), latch_frame=1),
        OraclePlane(point=(0.5, 0.5, 0.33), normal=(1, 0, 0), latch_frame=3),
    ]
    P = particles(x, vol, rho=1000.0, E=1e4, v=torch.tensor([0.0, 0.0, 0.2]).expand_as(x))
    cfg = S.TopologyConfig(provider="oracle", planes=planes, band_width=1.0)
    sim = S.Simulator(config(32, variant="full", dt=1e-3), P, device=device, provider=S.make_provider(cfg))
    latched = []
    for _ in range(5):
        n = len(sim.topologies)
        sim.advance(0.004)
        if len(sim.topologies) > n:
            latched.append(sim.frame)
        assert all(torch.isfinite(getattr(sim.particles, k)).all() for k in STATE)
    assert latched == [1, 3] and sim.n_fragments == 4, (latched, sim.n_fragments)  # 3 pieces, then the bottom halved
    # impulse-free: latching the last snapshot again changes nothing
    before = {k: getattr(sim.particles, k).clone() for k in STATE}
    sim.latch(sim.topology)
    for k, t in before.items():
        assert torch.equal(getattr(sim.particles, k), t), k
    assert [e.kind for e in sim.topology.events] == ["plane", "plane"]


def test_history_round_trip_and_replay(tmp_path, device):
    """save_history / load_history keep every snapshot's labels and events; ReplayProvider latches
    each snapshot at its frame."""
    x, vol = block((0.3, 0.3, 0.3), (0.7, 0.7, 0.7), 1 / 32)
    t0 = S.Topology.from_plane(x, (0.5, 0.5, 0.5), (1, 0, 0), 0.02, latch_frame=1)
    frag, band, parents, children = plane_cut(x, t0.fragment, t0.band, (0.5, 0.5, 0.5), (0, 1, 0), 0.02, 64)
    t1 = t0.refined(frag, band, S.topology.FractureEvent("plane", 0.03, 3, tuple(parents), tuple(children)))
    save_history(tmp_path / "topology.npz", [t0, t1])
    back = load_history(tmp_path / "topology.npz")
    assert len(back) == 2 and torch.equal(back[1].fragment, t1.fragment) and back[1].events[1].children == (2, 3)
    assert torch.equal(S.Topology.load(tmp_path / "topology.npz").fragment, t1.fragment)
    sim = S.Simulator(
        config(32, variant="full", dt=1e-3), particles(x, vol, E=1e4), device=device, provider=S.ReplayProvider(back)
    )
    for _ in range(4):
        sim.advance(0.002)
    assert [t.latch_frame for t in sim.topologies] == [1, 3] and sim.n_fragments == 4


@pytest.mark.slow
def test_voronoi_provider_shatters_on_contact(device):
    """A slab dropped on a floor shatters into the configured number of cells at its first contact,
    deterministically per seed; the band marks particles near cell faces."""
    dx = 1 / 32
    x, vol = block((0.3, 0.3, 0.3), (0.7, 0.7, 0.36), dx / 2)
    floor = S.PlaneBoundary(point=(0, 0, 0.25), normal=(0, 0, 1), mode="slip")
    runs = []
    for _ in range(2):
        cfg = S.TopologyConfig(provider="voronoi", cells=8, seed=3, latch_on_contact=True, impact_point=(0.5, 0.5, 0.3))
        sim = S.Simulator(
            config(32, variant="full", dt=1e-3, gravity=(0, 0, -9.8), boundaries=[floor]),
            particles(x, vol, E=2e4, v=torch.tensor([0.0, 0.0, -1.0]).expand_as(x)),
            device=device,
            provider=S.make_provider(cfg),
        )
        for _ in range(8):
            sim.advance(0.01)
        runs.append(sim)
    a, b = runs
    assert a.latched and a.topology.latch_frame >= 1, "no latch before the slab reaches the floor"
    assert a.n_fragments >= 8 and torch.equal(a.topology.fragment, b.topology.fragment)
    band = a.topology.band.bool()
    assert 0 < int(band.sum()) < len(band)


def test_fragment_aware_penetration_between_pieces(seed):
    """Two blocks touching face to face (jittered lattices) read less than 0.05Δx behind each other's
    surface, also turned at random (no preferred axis, no voxel staircase); pushed 3Δx into each other they
    read the kernel radius R (saturated: a lower bound), between fragments 0 and 1 only (scales calibrated
    while touching, as at a latch)."""
    from fracture_gs.sim.diagnostics.penetration import calibrate, surface_penetration

    dx = 1 / 32
    g = torch.Generator().manual_seed(seed)
    a, _ = block((0.3, 0.3, 0.3), (0.5, 0.6, 0.6), dx / 2, jitter=0.3, generator=g)
    b, _ = block((0.5, 0.3, 0.3), (0.7, 0.6, 0.6), dx / 2, jitter=0.3, generator=g)
    frag = torch.cat([torch.zeros(len(a)), torch.ones(len(b))]).int()
    R = rand_rotations(1, g)[0].float()
    for rot in (torch.eye(3), R):
        scales = calibrate(torch.cat([a, b]) @ rot.T, frag)  # as the tracker does at the latch: touching
        touching = surface_penetration(torch.cat([a, b]) @ rot.T, frag, 0.1 * dx, scales)
        assert touching["depth"] < 0.05 * dx and touching["crossing"] == 0, (seed, touching)
        pushed = surface_penetration(torch.cat([a, b - torch.tensor([3 * dx, 0, 0])]) @ rot.T, frag, 0.1 * dx, scales)
        assert pushed["depth"] > 0.99 * pushed["radius"] and pushed["crossing"] > 0, (seed, pushed["depth"] / dx)
        assert set(pushed["pairs"]) <= {(0, 1), (1, 0)}


def run_scene(name, particles, frames, variant="full"):
    from fracture_gs.io.config import load_config
    from fracture_gs.pipeline import load_scene, make_simulator, simulate

    cfg = load_config(name)
    cfg.particles, cfg.frames = particles, frames
    gs = load_scene(cfg)
    sim = make_simulator(cfg, gs, variant, "cpu")
    rows = [out.metrics for out in simulate(sim, gs.covariances().float(), cfg.frames, cfg.frame_dt)]
    return sim, rows


@pytest.mark.slow
def test_plate_drop_shatters_into_eight_or_more_pieces_without_interpenetration():
    """The plate hits the floor and the stress provider cuts it again and again: at least 8 pieces,
    every event impulse-free, no particle of one piece inside another's occupied voxels, none more than half a
    cell under the floor, no slot overflow, per-fragment mass conserved. The continuous depth behind another
    piece's surface (calibrated at each latch) reads no particle 0.1Δx deep once the pieces part (two frames
    after the first cut); in those two frames the first cut's layers, thinner than its density ball, lie
    together and it over-reads a little (≤ 3 particles, < 0.15Δx; with stored volumes it counted 90)."""
    sim, rows = run_scene("plate_drop", 8000, 40)
    post = [r for r in rows if r.get("latched")]
    assert sim.n_fragments >= 8, [r.get("fragments") for r in rows]
    assert len(sim.topology.events) >= 3 and all(e.kind == "plane" for e in sim.topology.events)
    assert max(r["voxel_crossing"] for r in post) == 0  # voxel occupancy, steps of 0.6Δx
    first = sim.topology.events[0].frame
    impact = [r for r in post if r["frame"] <= first + 1]
    apart = [r for r in post if r["frame"] > first + 1]
    assert len(apart) > 10 and max(r["fragment_crossing"] for r in apart) == 0
    assert max(r["fragment_penetration"] for r in apart) < 0.1
    assert max(r["fragment_crossing"] for r in impact) <= 3 and max(r["fragment_penetration"] for r in impact) < 0.15
    assert max(r["collider_crossing"] for r in post) == 0
    assert sum(r["slot_overflow"] for r in post) == 0
    assert max(max(r["mass_residual"]) for r in post) < 1e-5


@pytest.mark.slow
def test_bread_pulled_three_ways_tears_twice():
    """Held in the middle and pulled at both ends, the loaf is over-stressed in two separate places at
    once; the provider cuts each with its own plane in the same frame: three pieces, the middle one
    between the two planes."""
    sim, _ = run_scene("bread_three_way", 6000, 12)
    events = sim.topology.events
    assert sim.n_fragments == 3 and len(events) == 2
    xs = sorted(e.point[0] for e in events)
    assert xs[0] < 0.47 < 0.53 < xs[1], xs


@pytest.mark.slow
def test_solo_particles_skip_slot_claims_bitwise():
    """Particles no other fragment can reach this frame deposit into and read from the dense slot
    without claiming it; the fields and the trajectory equal those of claiming at every node (CPU,
    bitwise), and most particles of two separated halves are solo."""
    runs = []
    for solo in (True, False):
        x, vol = block((0.15, 0.4, 0.4), (0.85, 0.55, 0.55), 1 / 96)
        cfg = config(64, variant="full", dt=1e-3, gravity=(0.0, 0.0, -9.8), grid_storage="slots")
        sim = S.Simulator(cfg, particles(x, vol, E=1e4))
        sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 1 / 64))
        if not solo:
            sim.slots.update_solo = lambda travel, slack, slots=sim.slots: slots.set_solo(None)
        for _ in range(3):
            sim.advance(0.004)
        if solo:
            assert 0.5 < float(sim.slots.solo.float().mean()) < 1.0, "far from the cut the particles are solo"
        runs.append(sim)
    for k in ("x", "v", "C", "F"):
        assert torch.equal(getattr(runs[0].particles, k), getattr(runs[1].particles, k)), k


def _overlap_reference(x, fragment, h, K, max_depth=8):
    """A plain-Python twin of penetration.overlap_packed (dicts of voxels, the erosion spelled out)."""
    import math
    from collections import Counter

    pts = [tuple(p) for p in x.double().tolist()]
    frag = fragment.tolist()
    lo = [min(p[i] for p, f in zip(pts, frag) if f >= 0) for i in range(3)]
    cell = [tuple(math.floor((p[i] - lo[i]) / h) + 1 for i in range(3)) for p in pts]
    counts = Counter((c, f) for c, f in zip(cell, frag) if f >= 0)
    owner = {}
    for (c, f), n in sorted(counts.items()):
        if c not in owner or n > counts[(c, owner[c])]:
            owner[c] = f
    alive, level = set(owner), Counter()
    nbrs = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    for _ in range(max_depth):
        nxt = set()
        for c in alive:
            around = [tuple(a + d for a, d in zip(c, n)) for n in nbrs]
            if all(o in alive and owner[o] == owner[c] for o in around):
                nxt.add(c)
        alive = nxt
        for c in alive:
            level[c] += 1
    out = torch.zeros(2 + K * K, dtype=torch.float64)
    for c, f in zip(cell, frag):
        if f >= 0 and level[c] > 0 and owner[c] != f:
            d = level[c] * h
            out[0] += 1
            out[1] = max(out[1], d)
            out[2 + f * K + owner[c]] = max(out[2 + f * K + owner[c]], d)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_overlap_packed_matches_its_plain_twin(seed):
    """The vectorised fragment-overlap measure (sorted keys, binary searches, erosion by levels) equals a
    plain-Python twin on random interpenetrating pieces: crossing count, max depth and every pair's depth."""
    from fracture_gs.sim.diagnostics.penetration import overlap_packed

    g = torch.Generator().manual_seed(seed)
    K, h, n = 3, 0.02, 4000
    centres = torch.tensor([[0.3, 0.3, 0.3], [0.4, 0.3, 0.3], [0.3, 0.4, 0.33]])
    frag = torch.randint(0, K, (n,), generator=g)
    x = centres[frag] + 0.12 * (torch.rand(n, 3, generator=g) - 0.5)
    intruders = torch.rand(n, generator=g) < 0.01  # particles of another piece deep inside this one
    frag = torch.where(intruders, (frag + 1) % K, frag)
    frag[torch.rand(n, generator=g) < 0.01] = -1  # a few unlabelled particles
    x = x.float()
    got = overlap_packed(x, frag.int(), h, K)
    want = _overlap_reference(x, frag, h, K)
    torch.testing.assert_close(got, want, rtol=0, atol=1e-12)
    assert want[0] > 0  # the pieces do interpenetrate


@pytest.mark.parametrize("r", [1, 3, 6])
def test_solo_mask_cube_max_is_the_3d_max_pool(r):
    """The solo mask's neighbourhood max runs as three 1-D passes; max is separable, so it equals the
    (2r + 1)³ max pool exactly, empty (−inf) cells and the borders included."""
    from fracture_gs.sim.neighbourhood import _cube_max

    g = torch.Generator().manual_seed(r)
    t = torch.randn(1, 1, 17, 23, 11, generator=g)
    t[t > 1.0] = float("-inf")
    assert torch.equal(_cube_max(t, r), torch.nn.functional.max_pool3d(t, 2 * r + 1, stride=1, padding=r))


def test_pool_mass_gradients_are_central_differences_of_each_fields_mass(device, seed):
    """The mass-gradient contact normal's ∇m^k at a multi-fragment node (one thread per pool row and slot,
    before the pool pass: `grid.normal_kernels.pool_mass_gradients`) is the central difference
    (m^k(i + e_a) − m^k(i − e_a)) / 2Δx of fragment k's nodal masses, neighbours clamped into the grid
    (the float64 dense K-field reference), for every slot holding a field with mass; zero otherwise."""
    import warp as wp

    from fracture_gs.sim.grid.layout import OWNER_MASK
    from fracture_gs.sim.grid.normal_kernels import pool_mass_gradients

    sim, topo = voronoi_state(seed, device, variant="full")
    sim.latch(topo)
    P, g, dt = sim.particles, sim.grid, 1e-3
    sim.fit_active_box(0.0)
    sim.compute_stress(sim.stress, commit=True)
    K = sim.n_fragments
    args = (P.x.cpu(), P.v.cpu(), P.C.cpu(), P.mass.cpu(), P.volume.cpu(), sim.stress.cpu(), P.fragment.cpu().long())
    gm = ref.p2g(*args, K, g.shape, g.origin, g.dx, dt)[0].reshape(K, *g.shape)  # [K, X, Y, Z] float64
    sim.slots.set_solo(None)  # every particle through the slot claims
    sim.p2g(dt)
    grad0 = sim.slots.pool_gradient_buffer()
    wp.launch(pool_mass_gradients, dim=g.capacity * g.slots, device=sim.device, inputs=[g.view, sim.eps_m, grad0])
    rows = torch.nonzero(g.key.cpu() >= 0).flatten()
    assert len(rows) > 50, "pool rows where pieces meet"
    S1, n_nodes = g.slots - 1, g.n_nodes
    pad = torch.nn.functional.pad(gm[None], (1, 1, 1, 1, 1, 1), mode="replicate")[0]  # clamped neighbours
    checked = 0
    for r in rows.tolist():
        n = int(g.key[r])
        i, j, l = n // (g.shape[1] * g.shape[2]), (n // g.shape[2]) % g.shape[1], n % g.shape[2]  # noqa: E741
        for s in range(g.slots):
            if s == 0:
                k, got = int(g._owner[n] & OWNER_MASK) - 1, sim.slots.grad0[r].cpu().double()
            else:
                k, got = int(g.pool_owner[r * S1 + s - 1]), g._vel[n_nodes + r * S1 + s - 1].cpu().double()
            if k < 0 or float(gm[k, i, j, l]) <= sim.eps_m:
                assert torch.equal(got, torch.zeros(3, dtype=torch.float64)), (r, s)
                continue
            c = (i + 1, j + 1, l + 1)
            want = torch.stack(
                [
                    pad[k, c[0] + 1, c[1], c[2]] - pad[k, c[0] - 1, c[1], c[2]],
                    pad[k, c[0], c[1] + 1, c[2]] - pad[k, c[0], c[1] - 1, c[2]],
                    pad[k, c[0], c[1], c[2] + 1] - pad[k, c[0], c[1], c[2] - 1],
                ]
            ) * (0.5 / g.dx)
            scale = float(gm[k].max()) / g.dx
            assert float((got - want).abs().max()) <= 1e-5 * scale, f"row {r} slot {s} fragment {k} (seed {seed})"
            checked += 1
    assert checked > 100
