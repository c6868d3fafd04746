"""Hand-written bug campaign, round two: boundaries (`sim.physics.boundary`), each rule against hand values.

- A kinematic sphere acts over its whole window [start, end], both ends included, and not a step outside it.
- Coulomb friction on a plane shrinks the tangential speed by μ|v_n| and stops there: a node whose tangential speed
  is below μ|v_n| stops (v = 0), it never turns round; a weak friction leaves (1 − μ|v_n|/|v_t|) of it.
- A plane's `normal` is a direction, whatever its length: the same node gets the same velocity with normal
  (0, 0, 1), (0, 0, 2) or (0, 0, 0.5), in every mode.
- A timed region acts on the particles inside its box, its six faces included, and on none a step beyond any face;
  each axis against its own range (ranges that differ per axis, so reading another axis's bound shows).
- A timed region's window is exact to the substep: an impulse acts in the substeps that start in
  [start, start + max(end − start, Δt)) and adds Δv·Δt/duration in each (Δv in total); a velocity override acts in
  the substeps that start in [start, end + Δt/2] (a substep starting at `end`, up to rounding, is on).

Coordinates and times are powers of two where float32 holds them, so the comparisons are exact.
"""

import pytest
import torch
import warp as wp
from simutil import boundaries_applied

from fracture_gs.config import ParticleRegion, PlaneBoundary, SphereBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries, apply_particle_region

ensure_warp()


def _after(items, v, x, t=0.0) -> list:
    """`apply_boundaries` on nodes at x [M, 3] with velocities v [M, 3] at time t (no domain walls)."""
    return boundaries_applied(items, v, x, t, (16, 16, 16)).tolist()


def test_a_sphere_acts_from_its_start_to_its_end_both_included():
    """A ball at rest (radius 1/8 at (1/2, 1/2, 1/2), window [1/4, 1/2] s); a node 1/16 off its centre along +x,
    moving at (−1, 0, 0) into it: at t = start and at t = end the inward part is removed, v = 0; at 1/64 s before
    the start or after the end the node keeps (−1, 0, 0)."""
    ball = SphereBoundary(center=(0.5, 0.5, 0.5), radius=0.125, velocity=(0.0, 0.0, 0.0), start=0.25, end=0.5)
    node, v = [(0.5625, 0.5, 0.5)], [(-1.0, 0.0, 0.0)]
    for t in (0.25, 0.375, 0.5):
        assert _after([ball], v, node, t) == [[0.0, 0.0, 0.0]], f"t = {t}"
    for t in (0.25 - 1 / 64, 0.5 + 1 / 64):
        assert _after([ball], v, node, t) == [[-1.0, 0.0, 0.0]], f"t = {t}"


def test_coulomb_friction_stops_a_slow_slide_and_shrinks_a_fast_one():
    """A friction plane z = 3/4 (normal +z), a node at z = 1/2 behind it. μ = 2, v = (1/8, 0, −1): μ|v_n| = 2 exceeds
    |v_t| = 1/8, so the node stops, v = (0, 0, 0), not (1/8)(1 − 16) = −15/8 backwards. μ = 1/4, v = (1, 0, −1): the
    tangential part keeps 1 − 1/4 of itself, v = (3/4, 0, 0); the same along y, v = (0, 3/4, 0)."""
    x = [(0.5, 0.5, 0.5)]
    strong = PlaneBoundary(point=(0.0, 0.0, 0.75), normal=(0.0, 0.0, 1.0), mode="friction", friction=2.0)
    weak = PlaneBoundary(point=(0.0, 0.0, 0.75), normal=(0.0, 0.0, 1.0), mode="friction", friction=0.25)
    assert _after([strong], [(0.125, 0.0, -1.0)], x) == [[0.0, 0.0, 0.0]]
    assert _after([weak], [(1.0, 0.0, -1.0)], x) == [[0.75, 0.0, 0.0]]
    assert _after([weak], [(0.0, 1.0, -1.0)], x) == [[0.0, 0.75, 0.0]]


@pytest.mark.parametrize("mode,expected", [("slip", [0.5, 0.0, 0.0]), ("friction", [0.25, 0.0, 0.0])])
@pytest.mark.parametrize("length", [1.0, 2.0, 0.5])
def test_a_plane_takes_its_normals_direction_not_its_length(mode, expected, length):
    """A plane z = 3/4 with normal (0, 0, length), a node at z = 1/2 behind it moving at (1/2, 0, −1/4): slip
    removes the normal part, v = (1/2, 0, 0); friction μ = 1 also takes μ|v_n| = 1/4 off |v_t|, v = (1/4, 0, 0),
    whatever the normal's length (with the unnormalized (0, 0, 2), v_n would read −1/2 and v_t (1/2, 0, 3/4))."""
    plane = PlaneBoundary(point=(0.0, 0.0, 0.75), normal=(0.0, 0.0, length), mode=mode, friction=1.0)
    assert _after([plane], [(0.5, 0.0, -0.25)], [(0.5, 0.5, 0.5)]) == [expected]


def test_an_impulse_region_acts_in_the_substeps_that_start_in_its_window_and_adds_its_share():
    """Impulse Δv = (0, 0, 3) m/s over [1/8, 1/8 + 3/64] s, Δt = 1/64: on in the three substeps starting at 1/8,
    9/64 and 10/64, off at 7/64 and 11/64; each adds Δv·Δt/duration = (0, 0, 1). A window shorter than Δt lasts one
    substep and adds all of Δv in it."""
    dt = 1 / 64
    region = ParticleRegion(kind="impulse", lower=(0, 0, 0), upper=(1, 1, 1), delta_v=(0.0, 0.0, 3.0),
                            start=0.125, end=0.125 + 3 * dt)  # fmt: skip
    b = Boundaries([region], "cpu", (16, 16, 16), 0)
    times = [0.125 + k * dt for k in (-1, 0, 1, 2, 3)]
    on, value = b.region_table(times, dt)
    assert on == [0, 1, 1, 1, 0]
    assert value == [pytest.approx([0.0, 0.0, 1.0], abs=1e-12)] * 5
    short = ParticleRegion(kind="impulse", lower=(0, 0, 0), upper=(1, 1, 1), delta_v=(0.0, 0.0, 3.0),
                           start=0.125, end=0.125)  # fmt: skip
    on, value = Boundaries([short], "cpu", (16, 16, 16), 0).region_table([0.125, 0.125 + dt], dt)
    assert on == [1, 0] and value[0] == pytest.approx([0.0, 0.0, 3.0], abs=1e-12)


def test_a_velocity_region_covers_the_substep_that_starts_at_its_end():
    """Override window [1/8, 1/4] s, Δt = 1/64: the substep starting at 1/4 (and at 1/4 plus rounding, 1e-12) is on,
    the next one (1/4 + 1/64) and the one before the start are off."""
    dt = 1 / 64
    region = ParticleRegion(kind="velocity", lower=(0, 0, 0), upper=(1, 1, 1), velocity=(0.0, 1.0, 0.0),
                            start=0.125, end=0.25)  # fmt: skip
    b = Boundaries([region], "cpu", (16, 16, 16), 0)
    on, value = b.region_table([0.125 - dt, 0.125, 0.25, 0.25 + 1e-12, 0.25 + dt], dt)
    assert on == [0, 1, 1, 1, 0]
    assert value[1] == [0.0, 1.0, 0.0]


REGION_LO, REGION_HI = (0.125, 0.5, 0.25), (0.25, 0.625, 0.375)  # x, y and z ranges that do not overlap


def test_a_region_holds_its_six_faces_and_nothing_one_step_beyond_any_face():
    """A velocity region over [1/8, 1/4] × [1/2, 5/8] × [1/4, 3/8] setting (1, 2, 3): its centre and a particle on
    each of its six faces take (1, 2, 3); a particle 1/64 beyond any one face keeps v = 0."""
    centre = [(lo + hi) / 2 for lo, hi in zip(REGION_LO, REGION_HI)]
    inside, outside = [centre], []
    for a in range(3):
        for face, step in ((REGION_LO[a], -1 / 64), (REGION_HI[a], 1 / 64)):
            on, off = list(centre), list(centre)
            on[a], off[a] = face, face + step
            inside.append(on)
            outside.append(off)
    c = FrameClock("cpu", 1)
    c.set(1e-3, [0.0], on=[[1]], value=[[(1.0, 2.0, 3.0)]])
    x = wp.from_torch(torch.tensor(inside + outside, dtype=torch.float32), dtype=wp.vec3)
    v = wp.zeros(len(inside) + len(outside), dtype=wp.vec3, device="cpu")
    lo, hi = wp.vec3(*REGION_LO), wp.vec3(*REGION_HI)
    wp.launch(apply_particle_region, dim=v.shape[0], inputs=[x, v, lo, hi, 1, 0, c.view], device="cpu")
    got = v.numpy().tolist()
    assert got[: len(inside)] == [[1.0, 2.0, 3.0]] * len(inside)
    assert got[len(inside) :] == [[0.0, 0.0, 0.0]] * len(outside)
