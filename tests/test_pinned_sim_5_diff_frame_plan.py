"""The differentiable solver's frame plan (`sim.diff.solver.DiffSimulator`, host decisions only, no kernel runs).

- **The frame's box of nodes** (`_box`): the particles' bounding box in cells, widened on every side by
  pad = 5 + ⌈2 (max |v| T + ½ |g| T²) / Δx⌉ cells (the stencil, twice the distance a particle can travel in the
  frame: speed and the fall under gravity, both adding), cut to the grid: lo = max(0, ⌊(x_min − o)/Δx⌋ − pad),
  hi = min(shape, ⌊(x_max − o)/Δx⌋ + 1 + pad), per axis, shape = hi − lo.
- **The clock**: a new simulator is at t = 0, frame 0, with no plans; a plan starts at the simulator's time.
- **Routing after a latch**: a multi-field variant routes each particle to its fragment's field (K = max id + 1);
  a shared-field variant keeps one field (K = 1, every particle in field 0) whatever the topology, still with the
  band flags, and with stress release for the band particles of events 1 … release_events where the variant
  releases stress.
- **Which snapshot, which normal**: the latest snapshot latched at or before the frame; the contact normal is the
  first snapshot's n_Π made unit, (1, 0, 0) without any.
"""

from __future__ import annotations

import torch
from simutil import config

from fracture_gs.sim.diff.solver import DiffSimulator
from fracture_gs.sim.topology import Topology

DX = 1.0 / 32
ORIGIN = (0.25, -0.5, 1.0)


def _sim(x, gravity=(0.0, 0.0, 0.0), topologies=None, **kw):
    cfg = config(32, gravity=gravity, dt=1e-3, **kw)
    cfg.grid_origin = ORIGIN
    sim = DiffSimulator(cfg, x, "cpu", topologies=topologies)
    sim._x = x
    return sim


def _corners():
    """Two particles spanning cells 13 … 18 along x, 1 … 18 along y and 13 … 30 along z (offsets from the origin
    in cells: 13.12 / 18.88 along x, 1.6 / 18.88 along y, 13.12 / 30.4 along z), so the box meets the grid's
    lower face along y and its upper face along z once padded."""
    r = torch.tensor([[0.41, 0.05, 0.41], [0.59, 0.59, 0.95]], dtype=torch.float64)
    return (r + torch.tensor(ORIGIN, dtype=torch.float64)).float()


def _expected(pad):
    lo = (13 - pad, max(0, 1 - pad), 13 - pad)
    hi = (19 + pad, 19 + pad, min(32, 31 + pad))
    return lo, tuple(h - lo_ for lo_, h in zip(lo, hi))


def test_the_box_is_the_particles_cells_plus_the_stencil_and_cut_to_the_grid():
    """At rest without gravity the pad is the bare 5 cells: lo = (8, 0, 8) (y cut at the grid's first node),
    hi = (24, 24, 32) (z cut at the grid's end), shape = hi − lo. The grid is the explicit 32³ one at the origin."""
    x = _corners()
    sim = _sim(x, gravity=(0.0, 0.0, 0.0))
    assert sim.origin == ORIGIN and sim.dx == DX and tuple(sim.shape) == (32, 32, 32)
    lo, shape = sim._box(torch.zeros_like(x), 0.05)
    assert (lo, shape) == ((8, 0, 8), (16, 24, 24))
    assert (lo, shape) == _expected(5)


def test_the_box_widens_by_twice_the_fall_under_gravity():
    """g = (0, −6, −8), |g| = 10 m/s², at rest, T = 0.05 s: ½|g|T² = 12.5 mm, twice that is 0.8 cells → pad
    5 + ⌈0.8⌉ = 6; the fall widens the box (it never shrinks it), whatever the direction of g."""
    x = _corners()
    sim = _sim(x, gravity=(0.0, -6.0, -8.0))
    assert sim._box(torch.zeros_like(x), 0.05) == _expected(6) == ((7, 0, 7), (18, 25, 25))


def test_the_box_widens_by_twice_the_fastest_particles_travel_plus_the_fall():
    """The fastest particle (|v| = 0.5 m/s; the other at rest) and |g| = 10 m/s² over T = 0.05 s travel
    25 + 12.5 = 37.5 mm, twice that is 2.4 cells → pad 8 (speed and fall add: 25 − 12.5 mm would give 6, the speed
    alone 7). Without gravity a particle at 3 m/s over T = 0.01 s: 2 × 30 mm = 1.92 cells → pad 7."""
    x = _corners()
    v = torch.tensor([[0.3, 0.4, 0.0], [0.0, 0.0, 0.0]])
    sim = _sim(x, gravity=(0.0, -6.0, -8.0))
    assert sim._box(v, 0.05) == _expected(8) == ((5, 0, 5), (22, 27, 27))
    sim = _sim(x)
    v = torch.tensor([[0.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    assert sim._box(v, 0.01) == _expected(7)


def test_a_new_simulator_starts_at_time_zero_and_its_first_plan_there():
    """Frame 0 of a fresh simulator starts at t = 0 (a moving boundary is read at the time its plan starts at):
    time 0, frame 0, no plans yet; the first plan's t0 is 0 and spans n substeps of T / n."""
    x = _corners()
    sim = _sim(x)
    assert (sim.time, sim.frame, sim.plans) == (0.0, 0, [])
    plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
    assert plan.t0 == 0.0 and plan.n == 10 and plan.dt == 0.01 / 10
    assert (plan.lo, plan.shape) == _expected(5)


def _topology(latch_frame=0, normal=(0.0, 3.0, 4.0)):
    """Six particles: fragments 0, 0, 1, 1, 2, 2; band tags 0, 1, 2, 0, 1, 2 (event 1's band, event 2's band);
    release for the band of event 1 only."""
    return Topology(
        fragment=torch.tensor([0, 0, 1, 1, 2, 2], dtype=torch.int32),
        band=torch.tensor([0, 1, 2, 0, 1, 2], dtype=torch.int32),
        normal=normal,
        point=(0.0, 0.0, 0.0),
        latch_frame=latch_frame,
        release_events=1,
    )


def _six():
    r = 0.4 + 0.02 * torch.arange(18, dtype=torch.float64).reshape(6, 3)
    return (r + torch.tensor(ORIGIN, dtype=torch.float64)).float()


def test_after_a_latch_a_shared_field_variant_keeps_one_field_with_band_and_release():
    """`stress_zero` (shared field, stress release) after a latch of three fragments: one field, every particle in
    field 0; band flag 1 wherever γ ≠ 0; release factor 0 for the band of event 1 (γ = 1 ≤ release_events), 1 for
    event 2's band and outside. `probe_latch` releases nothing."""
    x = _six()
    sim = _sim(x, variant="stress_zero", topologies=[_topology()])
    plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
    assert plan.fields == 1
    assert plan.field.tolist() == [0] * 6 and plan.field.dtype == torch.int32
    assert plan.band.tolist() == [0.0, 1.0, 1.0, 0.0, 1.0, 1.0]
    assert plan.released.tolist() == [1.0, 0.0, 1.0, 1.0, 0.0, 1.0]
    sim = _sim(x, variant="probe_latch", topologies=[_topology()])
    plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
    assert plan.fields == 1 and plan.field.tolist() == [0] * 6
    assert plan.released.tolist() == [1.0] * 6 and plan.band.tolist() == [0.0, 1.0, 1.0, 0.0, 1.0, 1.0]


def test_after_a_latch_a_multifield_variant_routes_each_particle_to_its_fragment():
    """`local_multifield` and `full`: K = 3 fields for ids 0 … 2, each particle in its own fragment's field, the
    same band flags and release factors."""
    x = _six()
    for variant in ("local_multifield", "full"):
        sim = _sim(x, variant=variant, topologies=[_topology()])
        plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
        assert plan.fields == 3, variant
        assert plan.field.tolist() == [0, 0, 1, 1, 2, 2] and plan.field.dtype == torch.int32
        assert plan.band.tolist() == [0.0, 1.0, 1.0, 0.0, 1.0, 1.0]
        assert plan.released.tolist() == [1.0, 0.0, 1.0, 1.0, 0.0, 1.0]


def test_each_frame_takes_the_latest_snapshot_latched_by_then_and_the_first_ones_normal():
    """Snapshots latched at frames 3 and 1 (given out of order): none before frame 1, the frame-1 one for frames
    1 and 2, the frame-3 one from frame 3 on. The contact normal is the earliest snapshot's n_Π made unit
    ((0, 3, 4) → (0, 0.6, 0.8)); with no snapshot it is (1, 0, 0)."""
    x = _six()
    late, early = _topology(3, normal=(1.0, 0.0, 0.0)), _topology(1, normal=(0.0, 3.0, 4.0))
    sim = _sim(x, variant="full", topologies=[late, early])
    assert [sim.topology_at(f) for f in range(5)] == [None, early, early, late, late]
    assert sim._normal(None) == (0.0, 0.6, 0.8)
    assert _sim(x, variant="full")._normal(None) == (1.0, 0.0, 0.0)
