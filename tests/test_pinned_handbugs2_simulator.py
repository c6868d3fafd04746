"""Hand-written bug campaign, round two: the simulator's set-up and its frame bookkeeping (`sim.simulator`,
`sim.frames`), each rule against a hand computation.

- Thresholds: ε_m = sim.eps_mass·ρ̄Δx³ and ε_b = sim.eps_band·ρ̄Δx³, each from its own key (ρ̄Δx³ the mass of a
  full node).
- The CFL step is cfl·Δx / (max|v| + c), c = √((λ + 2μ)/ρ): the particles' own speed counts beside the wave speed.
- The divergence check counts a particle whose x, v, F or C is not finite, or whose speed exceeds Δx/Δt; each
  field on its own is enough.
- A redone frame restores everything a frame changes: the particles' state, the contact and the per-pair
  statistics and the counters.
"""

import math

import torch
from simutil import block, config, particles

from fracture_gs import sim as S

RHO, E, NU = 800.0, 2e5, 0.25


def _sim(**kw):
    x, vol = block((0.4, 0.4, 0.4), (0.5, 0.5, 0.5), 1 / 64)
    return S.Simulator(config(32, **kw), particles(x, vol, rho=RHO, E=E, nu=NU), device="cpu")


def test_each_contact_threshold_comes_from_its_own_key_times_a_full_nodes_mass():
    """ε_mass = 1e-3, ε_band = 0.25, ρ = 800 kg/m³, Δx = 1/32 m: ε_m = 1e-3·800/32³ kg, ε_b = 0.25·800/32³ kg."""
    sim = _sim(eps_mass=1e-3, eps_band=0.25)
    node = RHO / 32**3
    assert math.isclose(sim.eps_m, 1e-3 * node, rel_tol=1e-5)
    assert math.isclose(sim.eps_b, 0.25 * node, rel_tol=1e-5)


def test_the_cfl_step_counts_the_particle_speed_beside_the_wave_speed():
    """E = 2e5 Pa, ν = 1/4, ρ = 800: μ = 8e4, λ = 8e4, c = √(3·8e4/800) = √300 m/s; cfl = 0.4, Δx = 1/32:
    Δt = 0.4/32/√300 at rest and 0.4/32/(√300 + 5) at 5 m/s."""
    sim = _sim(cfl=0.4)
    c = math.sqrt(300.0)
    assert math.isclose(sim.wave_speed, c, rel_tol=1e-6)
    assert math.isclose(sim.cfl_dt(), 0.4 / 32 / c, rel_tol=1e-6)
    assert math.isclose(sim.cfl_dt(5.0), 0.4 / 32 / (c + 5.0), rel_tol=1e-6)


def test_the_divergence_check_counts_each_kind_of_bad_particle():
    """Δx = 1/32, Δt = 1e-3: one particle with a NaN in x, one with inf in F, one with NaN in C, one faster than
    Δx/Δt = 31.25 m/s (at 32 m/s) make 4; one at 31 m/s is fine."""
    sim = _sim()
    P = sim.particles
    P.x[0, 1] = float("nan")
    P.F[1, 2, 0] = float("inf")
    P.C[2, 0, 2] = float("nan")
    P.v[3] = torch.tensor([0.0, 32.0, 0.0])
    P.v[4] = torch.tensor([0.0, 0.0, 31.0])
    assert int(sim.runner.bad_particles(1e-3)) == 4
    P.x[0, 1] = 0.45
    P.C[2, 0, 2] = 0.0
    assert int(sim.runner.bad_particles(1e-3)) == 2


def test_a_redone_frame_gets_back_every_statistic_it_saved():
    """save_state, then every saved buffer is changed (particles, contact statistics, per-pair statistics,
    counters): restore_state brings each back bit for bit."""
    sim = _sim()
    P, g = sim.particles, sim.grid
    sim.runner.save_state()
    before = {k: getattr(P, k).clone() for k in sim.MUTABLE}
    stats, pairs, counts = g.contact_stats.clone(), g.pair_stats.clone(), sim.counts.clone()
    for k in sim.MUTABLE:
        getattr(P, k).add_(1.0)
    g.contact_stats.add_(3.0)
    g.pair_stats.add_(5.0)
    sim.counts.add_(7)
    sim.runner.restore_state()
    for k in sim.MUTABLE:
        assert torch.equal(getattr(P, k), before[k]), k
    assert torch.equal(g.contact_stats, stats)
    assert torch.equal(g.pair_stats, pairs)
    assert torch.equal(sim.counts, counts)
