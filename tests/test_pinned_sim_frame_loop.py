"""`sim/frames.py` host rules, a `FrameRunner` on a stand-in simulator (its methods read a few attributes): what a
recorded substep bakes in (a change means recording again), how a frame splits into substeps, which
particles count as diverged, and the diverged message's stated cause."""

import math
import types

import pytest
import torch

from fracture_gs.errors import SimulationDiverged, SimulationError
from fracture_gs.sim.frames import FrameRunner
from fracture_gs.sim.options import SimOptions


class Stub:
    """A stand-in simulator with the given attributes (the runner holds it weakly: keep it alive)."""

    def __init__(self, **attributes):
        self.__dict__.update(attributes)


def _keyed(boxed, layout=(1024, 8, 2), slots=((0, 0, 0, 8, 8, 8), 256, 1, 0, 4)):
    return Stub(
        multifield=boxed,
        latched=boxed,
        n_fragments=2,
        normal_mode=0,
        topology=None,
        record_contact=False,
        cfg=types.SimpleNamespace(wall_cells=3),
        clock=types.SimpleNamespace(capacity=16),
        options=SimOptions(concurrent=False),
        slots=types.SimpleNamespace(graph_key=lambda: slots),
        box_storage=types.SimpleNamespace(graph_key=lambda: layout) if boxed else None,
        boxed=boxed,
    )


def _key(sim) -> tuple:
    return FrameRunner(sim).graph_key()


def test_recorded_substep_is_recorded_again_when_the_fragment_boxes_grow():
    """With per-fragment boxes the substep's graph key holds the boxes' layout (capacity, overlap room, count):
    a grown layout changes the key. Without boxes (none allocated) the key has no layout part. The slot storage's
    part (active box, pool, fan-out, run length) is in the key either way."""
    a = _key(_keyed(True, (1024, 8, 2)))
    b = _key(_keyed(True, (2048, 8, 2)))
    assert a != b and a[-1] == (1024, 8, 2)
    assert _key(_keyed(False))[-1] is None
    moved = _key(_keyed(True, (1024, 8, 2), slots=((0, 0, 0, 9, 8, 8), 256, 1, 0, 4)))
    assert moved != a and moved[-1] == a[-1]


def _stepper(dt=1e-3, adaptive=False, cap=100, v=0.0, cfl=None):
    return Stub(
        cfg=types.SimpleNamespace(dt=dt, adaptive_dt=adaptive, max_substeps_per_frame=cap),
        particles=types.SimpleNamespace(v=torch.tensor([[v, 0.0, 0.0]])),
        cfl_dt=lambda vmax: cfl(vmax),
        grid=types.SimpleNamespace(dx=0.01),  # named by the refusal's message
    )


def _substeps(sim, frame_dt, vmax=None):
    return FrameRunner(sim).frame_substeps(frame_dt, vmax)


def test_a_frame_splits_into_equal_substeps_no_longer_than_dt():
    """n = ⌈frame_dt / dt⌉ equal substeps with n·Δt = frame_dt (a frame_dt that is a multiple of dt up to
    float noise takes exactly that many); more than max_substeps_per_frame is refused."""
    n, dt = _substeps(_stepper(dt=1e-3), 0.01)
    assert n == 10 and dt == pytest.approx(1e-3)
    n, dt = _substeps(_stepper(dt=0.1 / 3), 0.1)  # 0.1 / (0.1 / 3) = 3.0000000000000004
    assert n == 3
    n, dt = _substeps(_stepper(dt=3e-3), 0.01)
    assert n == 4 and dt == pytest.approx(2.5e-3)
    n, dt = _substeps(_stepper(dt=1e-3), 5e-4)  # a frame shorter than dt: one substep
    assert n == 1 and dt == 5e-4
    _substeps(_stepper(dt=1e-3, cap=10), 0.01)
    with pytest.raises(SimulationError, match="max_substeps_per_frame"):
        _substeps(_stepper(dt=1e-3, cap=9), 0.01)


def test_adaptive_substeps_take_the_cfl_bound_of_the_fastest_particle():
    """adaptive_dt: Δt ≤ min(dt, CFL(v_max)), v_max read from the particles when not given; an infinite v_max
    leaves dt as it is (the divergence check reports it)."""
    seen = []

    def cfl(vmax):
        seen.append(vmax)
        return 0.01 / (1.0 + vmax)

    n, _ = _substeps(_stepper(dt=1e-3, adaptive=True, v=9.0, cfl=cfl), 0.01)
    assert seen == [9.0] and n == 10  # CFL 1e-3 = dt
    n, _ = _substeps(_stepper(dt=1e-3, adaptive=True, cfl=cfl), 0.01, vmax=19.0)
    assert n == 20
    n, _ = _substeps(_stepper(dt=1e-3, adaptive=True, cfl=cfl), 0.01, vmax=math.inf)
    assert n == 10 and seen[-1] == 19.0
    n, _ = _substeps(_stepper(dt=1e-3, adaptive=False, cfl=cfl), 0.01, vmax=1e6)
    assert n == 10


def _particles(n=4):
    return types.SimpleNamespace(
        x=torch.zeros(n, 3), v=torch.zeros(n, 3), F=torch.eye(3).repeat(n, 1, 1), C=torch.zeros(n, 3, 3)
    )


def test_diverged_particles_are_non_finite_or_faster_than_a_cell_per_substep():
    """A particle counts as diverged when x, v, F or C holds a non-finite entry or its speed exceeds Δx/Δt;
    exactly Δx/Δt is still fine."""
    P = _particles(6)
    dx, dt = 0.1, 0.01  # Δx/Δt = 10 m/s
    P.v[0, 0] = 10.0
    P.v[1, 1] = 10.5
    P.F[2, 1, 2] = float("nan")
    P.C[3, 0, 0] = float("inf")
    P.x[4, 2] = float("-inf")
    sim = Stub(particles=P, grid=types.SimpleNamespace(dx=dx))
    assert int(FrameRunner(sim).bad_particles(dt)) == 4


def test_diverged_message_blames_the_cfl_bound_only_when_dt_exceeds_it():
    """The divergence error names the CFL bound as the cause when Δt is over it, otherwise an extreme
    deformation or boundary velocity."""
    sim = Stub(cfl_dt=lambda: 1e-3, wave_speed=50.0, frame=7, time=0.5, particles=[0] * 10)
    with pytest.raises(SimulationDiverged, match="over the CFL bound") as e:
        FrameRunner(sim).raise_diverged(2e-3, 3)
    assert e.value.count == 3 and e.value.frame == 7
    with pytest.raises(SimulationDiverged, match="extreme deformation"):
        FrameRunner(sim).raise_diverged(1e-3, 3)
