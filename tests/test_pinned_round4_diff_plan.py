"""The differentiable solver's host decisions (`sim.diff.solver.DiffSimulator`), no kernel run:

* a frame of length T takes n = ⌈T/Δt⌉ substeps of T/n each, with a 1e-9 tolerance so that a frame that is a
  whole number of steps (1.5 ms of 0.3 ms, 5.000000000000001 in floating point) takes exactly that many, and at
  least one substep even for a frame of length 0 (a substep of 0 s, never a division by zero);
* with adaptive Δt the step is min(sim.dt, CFL·Δx / (max |v| + wave speed));
* before any latch every particle is routed to field 0, with no band and no stress release;
* on a CUDA device, Warp's pool is told to keep the tape memory of the run's N particles (x0's first axis).
"""

from __future__ import annotations

import math

import pytest
import torch
from simutil import block, config

from fracture_gs.sim.diff import solver as S
from fracture_gs.sim.diff.solver import DiffSimulator


def _sim(**kw):
    x, _ = block((0.4, 0.4, 0.4), (0.6, 0.6, 0.6), 1.0 / 32)
    sim = DiffSimulator(config(32, **kw), x, "cpu")
    sim._x = x
    return sim, x


@pytest.mark.parametrize(
    "dt, frame_dt, n",
    [
        (1e-3, 0.01, 10),
        (1e-3, 0.0105, 11),
        (1e-3, 0.0009, 1),
        (1e-3, 0.001, 1),
        (1e-3, 0.0010001, 2),
        (1e-3, 0.0, 1),
        (3e-4, 0.0015, 5),  # 0.0015 / 3e-4 = 5.000000000000001 in floating point
        (0.01, 0.07, 7),  # 7.000000000000001
    ],
)
def test_a_frame_takes_the_fewest_whole_substeps_of_at_most_dt(dt, frame_dt, n):
    """Fixed Δt: ⌈T/Δt⌉ substeps (a whole number of steps not rounded up by floating point, a frame shorter than
    Δt or of length 0 in one), each T/n long, starting at the simulator's time."""
    assert 0.0015 / 3e-4 > 5 and 0.07 / 0.01 > 7
    sim, x = _sim(dt=dt)
    sim.time = 0.25
    plan = sim.plan(0, torch.zeros_like(x), frame_dt, 0.0)
    assert plan.n == n
    assert plan.dt == frame_dt / n and plan.dt <= dt * (1 + 1e-12)
    assert plan.t0 == 0.25


def test_adaptive_dt_follows_the_cfl_bound_of_the_fastest_particle_plus_the_wave_speed():
    """CFL 0.5, Δx = 1/32 m, max |v| = 3 m/s (one particle), wave speed 7 m/s: the bound is 0.5/32/10 =
    1.5625 ms. Under sim.dt = 10 ms a 10 ms frame takes ⌈6.4⌉ = 7 substeps; under sim.dt = 1 ms the fixed step
    is the smaller one and the frame takes 10."""
    for dt, n in ((1e-2, 7), (1e-3, 10)):
        x, _ = block((0.4, 0.4, 0.4), (0.6, 0.6, 0.6), 1.0 / 32)
        sim = DiffSimulator(config(32, dt=dt, adaptive_dt=True, cfl=0.5), x, "cpu", wave_speed=7.0)
        sim._x = x
        v = torch.zeros_like(x)
        v[5] = torch.tensor([0.0, 3.0, 0.0])
        plan = sim.plan(0, v, 0.01, 0.0)
        assert plan.n == n
        assert plan.dt == pytest.approx(0.01 / n, rel=1e-12)
    assert math.ceil(0.01 / (0.5 / 32 / 10)) == 7


def test_before_a_latch_every_particle_is_in_field_0_without_band_or_release():
    """No topology: one field, field ids 0, band 0 and release factor 1 for every particle (as int32 / float32
    tensors of the particle count)."""
    sim, x = _sim(dt=1e-3, variant="full")
    plan = sim.plan(0, torch.zeros_like(x), 0.01, 0.0)
    N = x.shape[0]
    assert plan.fields == 1
    assert plan.field.dtype == torch.int32 and torch.equal(plan.field, torch.zeros(N, dtype=torch.int32))
    assert torch.equal(plan.band, torch.zeros(N)) and torch.equal(plan.released, torch.ones(N))


class _Reserved(Exception):
    pass


def test_a_cuda_run_keeps_tape_memory_for_its_particle_count(monkeypatch):
    """DiffSimulator on "cuda:0" asks `_keep_tape_memory` for that device and N = x0.shape[0] particles (not the 3
    of a position's coordinates) before anything else touches the device; on the CPU it does not ask at all.
    The call is intercepted (no GPU needed): the recorder stops the constructor right there."""
    calls = []

    def record(device, n):
        calls.append((device, n))
        raise _Reserved

    monkeypatch.setattr(S, "_keep_tape_memory", record)
    x, _ = block((0.4, 0.4, 0.4), (0.6, 0.6, 0.6), 1.0 / 32)
    assert x.shape[0] == 216
    with pytest.raises(_Reserved):
        DiffSimulator(config(32), x, "cuda:0")
    assert calls == [("cuda:0", 216)]
    DiffSimulator(config(32), x, "cpu")
    assert calls == [("cuda:0", 216)]
