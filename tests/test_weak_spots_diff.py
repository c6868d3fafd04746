"""Weak spots of the differentiable path (issue 34): which band particles a frame releases, and the band mass its
P2G deposits. The float64 twin (`diff.reference`) takes both from the plan and from the same definition, so a bug
in either is invisible to the gradient checks: these tests state the rules directly. Every test names the bug it
was checked against (applied by hand to the package, the test failed, then reverted)."""

import pytest
import torch
import warp as wp
from simutil import block, config

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.diff import DiffSimulator
from fracture_gs.sim.diff import kernels as K
from fracture_gs.sim.topology import Topology


def latched(variant: str, release_events: int):
    """A block cut at x = 0.5 (event 1's band tagged 1) and again at y = 0.5 (untagged particles of its band tagged
    2), latched at frame 0: a DiffSimulator on it and the topology."""
    x, _ = block((0.3, 0.3, 0.3), (0.7, 0.7, 0.5), 1.0 / 32)
    band = torch.zeros(len(x), dtype=torch.int32)
    band[(x[:, 0] - 0.5).abs() < 0.04] = 1
    band[((x[:, 1] - 0.5).abs() < 0.04) & (band == 0)] = 2
    fragment = (x[:, 0] >= 0.5).to(torch.int32) + 2 * (x[:, 1] >= 0.5).to(torch.int32)
    topo = Topology(fragment=fragment, band=band, normal=(1.0, 0.0, 0.0), point=(0.5, 0.5, 0.5), latch_frame=0)
    topo.release_events = release_events
    sim = DiffSimulator(config(32, variant=variant, dt=1e-3), x, "cpu", topologies=[topo])
    sim._x = x
    return sim, topo, x


@pytest.mark.parametrize(
    "variant,release_events,released_tags",
    [
        ("full", 1, {1}),
        ("full", 1 << 30, {1, 2}),
        ("full", 0, set()),
        ("local_multifield", 1, {1}),
        ("baseline", 1, set()),
    ],
)
def test_a_frame_releases_the_band_of_events_one_to_release_events(variant, release_events, released_tags):
    """Eq. stress_release on the differentiable path: after a latch, band particles of events 1 … release_events
    (`topology.release = "first"`: 1, `"all"`: every event, `"none"`: 0) carry no stress (factor 1 − γ_p = 0),
    every other particle its full stress (1), in variants with release; baseline releases nothing. The plan also
    marks every band particle (any tag) for the contact gate.
    Bugs tried: `(b != 0) & (b <= release_events)` as `(b > 1) & …` (the first event's band never released), as
    `b < release_events`; `released` ignoring `spec.release`; the gate's band marking only tag 1. Each fails here."""
    sim, topo, x = latched(variant, release_events)
    plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
    band = topo.band
    assert set(band.unique().tolist()) == {0, 1, 2}
    want = torch.ones(len(x))
    for tag in released_tags:
        want[band == tag] = 0.0
    assert torch.equal(plan.released.cpu(), want)
    assert torch.equal(plan.band.cpu(), (band != 0).float()), "every band particle feeds the contact gate"


def test_band_mass_is_the_band_particles_mass_on_the_grid():
    """Eq. band_mass: m_band,i^k = Σ_p γ_p w_ip m_p. With every particle in the band (γ = 1) each node's band mass
    equals its mass (both partitions of unity times m_p), and with γ = ½ it is half; particle masses far from 1 make
    a dropped m_p visible. Also Σ_i m_i = Σ_p m_p (the weights sum to one).
    Bug tried: `band[p] * weight * m` as `band[p] * weight` (band mass deposited without the particle mass): fails
    here."""
    ensure_warp()
    n = 16
    x, vol = block((0.3, 0.3, 0.3), (0.6, 0.6, 0.6), 1.0 / 40, jitter=0.5, generator=torch.Generator().manual_seed(1))
    N = len(x)
    mass = 0.2 + 3.0 * torch.rand(N, generator=torch.Generator().manual_seed(2))
    cells = n**3
    for gamma in (1.0, 0.5):
        gm, gb = wp.zeros(cells, dtype=float), wp.zeros(cells, dtype=float)
        gp = wp.zeros(cells, dtype=wp.vec3)
        inputs = [
            wp.from_torch(x.contiguous(), dtype=wp.vec3),
            wp.zeros(N, dtype=wp.vec3),
            wp.zeros(N, dtype=wp.mat33),
            wp.zeros(N, dtype=wp.mat33),
            wp.from_torch(mass.contiguous()),
            wp.from_torch(torch.full((N,), vol)),
            wp.zeros(N, dtype=wp.int32),
            wp.from_torch(torch.full((N,), gamma)),
            1e-3,
            wp.vec3(0.0, 0.0, 0.0),
            1.0 / n,
            float(n),
            wp.vec3i(n, n, n),
        ]
        wp.launch(K.p2g, dim=N, inputs=inputs, outputs=[gm, gp, gb], device="cpu")
        m, b = wp.to_torch(gm).double(), wp.to_torch(gb).double()
        assert float(m.sum()) == pytest.approx(float(mass.double().sum()), rel=1e-5)
        torch.testing.assert_close(b, gamma * m, rtol=1e-5, atol=1e-7)


def test_a_frame_runs_on_the_topology_latched_at_or_before_it():
    """`topology_at(f)`: a topology latched at frame L (the simulator's frame counter when the provider returned it,
    after frame L − 1's substeps) routes frames L, L + 1, …; frame L − 1 still runs on the shared field.
    Bug tried: `t.latch_frame <= frame` as `<` (every latch one frame late): fails here."""
    sim, topo, x = latched("full", 1)
    topo.latch_frame = 1
    assert sim.plan(0, torch.zeros_like(x), 0.01, 0.0).fields == 1
    assert sim.plan(1, torch.zeros_like(x), 0.01, 0.0).fields == 4


@pytest.mark.parametrize("speed", [0.0, 1.0])
def test_a_frames_fields_hold_every_stencil_its_particles_can_reach(speed):
    """The differentiable frame's fields cover a box of the grid (`FramePlan.lo`, `shape`): the particles' bounds
    plus the stencil and their travel over the frame, so every stencil (base = ⌊ξ − ½⌋ … base + 2) at the frame's
    start and after moving v · frame_dt (at rest, or 6.4 Δx) lies inside it (one outside would be clamped onto the
    box's edge).
    Bugs tried: `pad = 5 + …` as `pad = 0 + …` and the travel term dropped; each fails here."""
    sim, _, x = latched("full", 1)
    v = speed * torch.tensor([10.0, -3.0, 2.0]).expand_as(x)  # 6.4 Δx in x over the frame (or at rest)
    frame_dt = 0.02
    plan = sim.plan(0, v, frame_dt, 0.0)
    lo, shape = torch.tensor(plan.lo), torch.tensor(plan.shape)
    for moved in (x, x + v * frame_dt):
        xi = (moved.double() - torch.tensor(sim.origin, dtype=torch.float64)) / sim.dx
        base = torch.floor(xi - 0.5).long() - lo
        assert bool((base >= 0).all() and (base + 2 < shape).all()), (plan.lo, plan.shape)
