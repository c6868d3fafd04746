"""The differentiable solver's substep count (`sim.diff.solver.DiffSimulator.plan`, host decisions only).

With `adaptive_dt` the substep is Δt = min(cfg.dt, cfl·Δx / (max |v| + c)), c the `wave_speed` the simulator was
given (0 by default: the particles' speed alone), and a frame of length T takes n = ⌈T / Δt⌉ substeps of T / n.
At rest with c = 0 nothing bounds Δt but cfg.dt (no division by zero). Without `adaptive_dt`, Δt = cfg.dt
whatever the speed. Grid: 32³ cells of Δx = 1/32 m; cfl = 0.4, so cfl·Δx = 0.0125 m."""

import pytest
import torch
from simutil import config

from fracture_gs.sim.diff.solver import DiffSimulator

T = 0.01  # frame length [s]


def _sim(adaptive=True, **kw):
    x = torch.tensor([[0.4, 0.4, 0.4], [0.6, 0.5, 0.45], [0.5, 0.6, 0.55]])
    cfg = config(32, dt=0.01, adaptive_dt=adaptive, cfl=0.4)
    sim = DiffSimulator(cfg, x, "cpu", **kw)
    sim._x = x
    return sim


def _speed(s):
    """Velocities [3, 3]: one particle at speed s along (3, 4, 0)/5, the others at rest."""
    v = torch.zeros(3, 3)
    v[1] = torch.tensor([0.6 * s, 0.8 * s, 0.0])
    return v


def test_the_default_wave_speed_is_zero_so_the_fastest_particle_alone_sets_the_substep():
    """|v| = 5 m/s, c = 0 by default: Δt = 0.0125 / 5 = 2.5 ms → a 10 ms frame takes exactly 4 substeps of 2.5 ms
    (a default c of 1 m/s would give 2.08 ms → 5)."""
    sim = _sim()
    assert sim.wave_speed == 0.0
    plan = sim.plan(0, _speed(5.0), T, 1.0)
    assert plan.n == 4 and plan.dt == pytest.approx(T / 4, rel=1e-12)


@pytest.mark.parametrize("c, n", [(5.0, 8), (19.0, 20), (1.0, 5)])
def test_a_given_wave_speed_adds_to_the_particle_speed(c, n):
    """|v| = 5 m/s plus c: Δt = 0.0125 / (5 + c), n = ⌈0.01 / Δt⌉ — c = 5 → 8, c = 19 → ⌈19.2⌉ = 20
    (0.0125/24 = 0.52 ms: 19 substeps would be too long), c = 1 → ⌈4.8⌉ = 5."""
    plan = _sim(wave_speed=c).plan(0, _speed(5.0), T, 1.0)
    assert plan.n == n and plan.dt == pytest.approx(T / n, rel=1e-12)


def test_at_rest_without_a_wave_speed_the_substep_is_the_configured_bound():
    """No particle moves and c = 0: the CFL bound is unbounded, so Δt = cfg.dt = 10 ms and the frame is one
    substep (it used to divide by zero); with c = 2.5 m/s at rest Δt = 5 ms → 2 substeps."""
    assert _sim().plan(0, torch.zeros(3, 3), T, 1.0).n == 1
    assert _sim(wave_speed=2.5).plan(0, torch.zeros(3, 3), T, 1.0).n == 2


def test_without_adaptive_dt_the_speed_does_not_change_the_substep():
    """adaptive_dt off: Δt = cfg.dt = 10 ms however fast the particles or the waves — one substep per 10 ms frame,
    three per 30 ms frame."""
    sim = _sim(adaptive=False, wave_speed=100.0)
    assert sim.plan(0, _speed(50.0), T, 1.0).n == 1
    assert sim.plan(0, _speed(50.0), 3 * T, 1.0).n == 3
