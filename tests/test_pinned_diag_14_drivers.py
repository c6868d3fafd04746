"""`energy.drivers_active`: which boundaries drive motion in a frame, and the exact window of each.

A cuboid or sphere with a non-zero velocity drives in [start, end]; an impulse region in
[start, start + max(end − start, Δt)] (a zero-length impulse still acts for one substep); a velocity region in
[start, end + Δt/2]. A frame whose substeps start in [t0, t1) sees a driver when start < t1 and its window's end
≥ t0. All times below are binary fractions, so every boundary comparison is exact."""

import pytest

from fracture_gs.config import CuboidBoundary, ParticleRegion, PlaneBoundary, SphereBoundary
from fracture_gs.sim.diagnostics.energy import drivers_active


def _windows(b, dt: float = 0.0) -> list[bool]:
    """drivers_active for b over frames probing both sides of its start and of its end."""
    frames = [(0.5, 1.0), (0.75, 1.25), (1.25, 1.5), (1.5, 1.75), (1.75, 2.0), (2.0, 2.25), (2.25, 2.5), (3.5, 4.0)]
    return [drivers_active([b], t0, t1, dt) for t0, t1 in frames]


@pytest.mark.parametrize(
    "b",
    [
        CuboidBoundary(velocity=(0.0, 0.0, -1.0), start=1.0, end=2.0),
        SphereBoundary(radius=0.1, velocity=(0.5, 0.0, 0.0), start=1.0, end=2.0),
    ],
)
def test_a_moving_cuboid_or_sphere_drives_from_its_start_through_its_end(b):
    """Window [start, end] = [1, 2]: a frame ending at the start (t1 = 1, start < t1 fails) is not driven, a frame
    starting exactly at the end (end ≥ t0) is, and one after the end is not."""
    assert _windows(b) == [False, True, True, True, True, True, False, False]


def test_a_still_cuboid_or_a_plane_never_drives():
    """Zero velocity (or a static plane) only removes energy: no frame of any length sees a driver."""
    still = CuboidBoundary(velocity=(0.0, 0.0, 0.0), start=0.0, end=10.0)
    assert not drivers_active([still, PlaneBoundary()], 0.0, 100.0, 0.1)


def test_an_impulse_acts_until_its_end_or_one_substep_whichever_is_longer():
    """Impulse from 1 to 1.5: driven in frames starting up to 1.5 (its end), not after, for a short Δt; a Δt of
    0.75 (longer than the window) stretches it to start + Δt = 1.75. A zero-length impulse at 1 acts for one
    substep: to 1.25 with Δt = 0.25, to 1 with Δt = 0 (the default)."""
    kick = ParticleRegion(kind="impulse", delta_v=(0.0, 1.0, 0.0), start=1.0, end=1.5)
    assert _windows(kick, 0.25) == [False, True, True, True, False, False, False, False]
    assert _windows(kick, 0.75) == [False, True, True, True, True, False, False, False]
    tap = ParticleRegion(kind="impulse", delta_v=(0.0, 0.0, 2.0), start=1.0, end=1.0)
    assert _windows(tap, 0.25) == [False, True, True, False, False, False, False, False]
    assert _windows(tap) == [False, True, False, False, False, False, False, False]
    zero = ParticleRegion(kind="impulse", delta_v=(0.0, 0.0, 0.0), velocity=(1.0, 1.0, 1.0), start=1.0, end=1.5)
    assert not any(_windows(zero, 0.25)), "an impulse region drives by its delta_v, not its velocity"


def test_a_velocity_region_holds_until_half_a_substep_past_its_end():
    """Velocity override from 1 to 1.5 with Δt = 0.5: its window ends at 1.5 + 0.25 = 1.75, so a frame starting at
    1.75 is driven and one starting at 2 is not; without Δt it ends at 1.5."""
    grip = ParticleRegion(kind="velocity", velocity=(0.0, -1.0, 0.0), delta_v=(0.0, 0.0, 0.0), start=1.0, end=1.5)
    assert _windows(grip, 0.5) == [False, True, True, True, True, False, False, False]
    assert _windows(grip) == [False, True, True, True, False, False, False, False]
    still = ParticleRegion(kind="velocity", velocity=(0.0, 0.0, 0.0), delta_v=(1.0, 0.0, 0.0), start=1.0, end=1.5)
    assert not any(_windows(still, 0.5)), "a velocity region drives by its velocity, not its delta_v"


def test_any_one_driving_boundary_among_many_is_enough():
    """The answer is an any() over the list: a still cuboid and a plane before a moving sphere do not hide it."""
    still, plane = CuboidBoundary(), PlaneBoundary()
    ball = SphereBoundary(radius=0.1, velocity=(0.0, 0.0, 1.0), start=1.0, end=2.0)
    assert drivers_active([still, plane, ball], 1.5, 1.75) and not drivers_active([still, plane, ball], 2.25, 2.5)
