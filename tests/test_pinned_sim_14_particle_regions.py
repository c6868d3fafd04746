"""Timed particle regions (`sim.physics.boundary`):

- a region's box is closed: particles on any of its six faces are inside, one float32 step beyond any face is
  outside — on every axis, against that axis's own bounds;
- `Boundaries.apply_regions` launches every region when it is given no on-flags (a captured graph: each region
  then reads its activity from the clock's table itself), and only the regions whose host flag is on when it is
  given this substep's flags (the host knows the table: the others are not launched at all).

Coordinates are powers of two, so float32 holds them and the faces exactly."""

import torch
import warp as wp

from fracture_gs.config import ParticleRegion
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries, apply_particle_region

ensure_warp()

LOWER, UPPER = (0.125, 0.5, 0.25), (0.25, 0.625, 0.375)  # x, y and z ranges that do not overlap
SET = (1.0, 2.0, 3.0)


def _after(points, lower=LOWER, upper=UPPER):
    """Velocities after a velocity-override region [lower, upper] (active) on particles at rest at `points`."""
    c = FrameClock("cpu", 1)
    c.set(1e-3, [0.0], on=[[1]], value=[[SET]])
    x = wp.from_torch(torch.tensor(points, dtype=torch.float32), dtype=wp.vec3)
    v = wp.zeros(len(points), dtype=wp.vec3, device="cpu")
    wp.launch(apply_particle_region, dim=len(points), inputs=[x, v, wp.vec3(*lower), wp.vec3(*upper), 1, 0, c.view])
    return [tuple(p) for p in v.numpy().tolist()]


def test_a_region_holds_its_six_faces_and_nothing_one_float_step_beyond():
    """The box's centre and a particle on each of its six faces take the region's velocity; a particle one float32
    step outside any one face keeps its rest."""
    centre = [(lo + hi) / 2 for lo, hi in zip(LOWER, UPPER)]
    inside, outside = [centre], []
    for a in range(3):
        for face, away in ((LOWER[a], -1.0), (UPPER[a], 1.0)):
            on = list(centre)
            on[a] = face
            inside.append(on)
            off = list(centre)
            off[a] = float(torch.nextafter(torch.tensor(face), torch.tensor(face + away)))
            outside.append(off)
    assert _after(inside) == [SET] * 7
    assert _after(outside) == [(0.0, 0.0, 0.0)] * 6


def _two_regions():
    """An impulse region (Δv = (0, 0, 2) over one substep) over x < 0.5 and a velocity override (1, 0, 0) over
    x > 0.5, both active from t = 0 for a long time."""
    a = ParticleRegion(kind="impulse", lower=(0, 0, 0), upper=(0.5, 1, 1), delta_v=(0, 0, 2), start=0.0, end=0.0)
    b = ParticleRegion(kind="velocity", lower=(0.5, 0, 0), upper=(1, 1, 1), velocity=(1, 0, 0), start=0.0, end=10.0)
    return Boundaries([a, b], "cpu")


def _apply(active):
    """Particles at rest at x = 0.25 (region 0) and x = 0.75 (region 1); the clock's table says both are on this
    substep; apply_regions with the host flags `active`."""
    bnd = _two_regions()
    dt = 1e-3
    on, value = bnd.region_table([0.0], dt)
    assert on == [1, 1] and value == [[0.0, 0.0, 2.0], [1.0, 0.0, 0.0]]
    c = FrameClock("cpu", 2)
    c.set(dt, [0.0], on=[on], value=[value])
    x = wp.from_torch(torch.tensor([[0.25, 0.5, 0.5], [0.75, 0.5, 0.5]]), dtype=wp.vec3)
    v = wp.zeros(2, dtype=wp.vec3, device="cpu")
    bnd.apply_regions(x, v, 2, c.view, "cpu", active)
    return v.numpy().tolist()


def test_without_flags_every_region_is_launched_and_reads_its_table():
    """No host flags: both regions act (the impulse adds its whole Δv in its one substep, the override sets)."""
    assert _apply(None) == [[0.0, 0.0, 2.0], [1.0, 0.0, 0.0]]


def test_with_host_flags_only_the_regions_flagged_on_are_launched():
    """Flags (1, 0): only the impulse acts; (0, 1): only the override; (0, 0): nothing — though the clock's
    table has both on."""
    assert _apply([1, 0]) == [[0.0, 0.0, 2.0], [0.0, 0.0, 0.0]]
    assert _apply([0, 1]) == [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    assert _apply([0, 0]) == [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
