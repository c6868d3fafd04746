"""`metrics.collider_packed` and its host twin `collider_crossing`: particles behind plane colliders.

For each plane, d = (x − point)·n̂; a particle counts when d < −tolerance (strictly: exactly at the tolerance it
does not), in the count of every plane it is behind; the depth is the deepest −d over all planes. Distances are
exact binary fractions, so the expected numbers are exact."""

import torch

from fracture_gs.config import PlaneBoundary
from fracture_gs.sim.diagnostics.metrics import collider_crossing, collider_packed

TOL = 0.25


def _scene():
    """A floor z = 0 (normal +z) and a wall x = 1 (normal −x, given unnormalised)."""
    floor = PlaneBoundary(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))
    wall = PlaneBoundary(point=(1.0, 0.0, 0.0), normal=(-4.0, 0.0, 0.0))
    x = torch.tensor(
        [
            [0.5, 0.5, -0.25],  # exactly at the tolerance below the floor: not counted
            [0.5, 0.5, -0.5],  # 0.5 below the floor
            [0.5, 0.5, -0.375],  # 0.375 below the floor
            [1.75, 0.5, 0.5],  # 0.75 behind the wall
            [1.25, 0.5, 0.5],  # exactly at the tolerance behind the wall: not counted
            [0.5, 0.5, 3.0],  # free
        ],
        dtype=torch.float32,
    )
    return x, [floor, wall]


def test_packed_counts_and_depth_over_every_plane():
    """Three particles beyond the tolerance (two under the floor, one behind the wall): count 3, deepest 0.75 (the
    wall's, after the floor's 0.5); the two exactly at the tolerance are not counted."""
    x, planes = _scene()
    assert collider_packed(x, planes, TOL).tolist() == [3.0, 0.75]
    assert collider_crossing(x, planes, TOL) == (3, 0.75)


def test_the_deepest_plane_wins_whatever_the_order():
    """Planes in the other order give the same count and depth (the depth is a running maximum, not the last
    plane's, and the count a running sum)."""
    x, planes = _scene()
    assert collider_packed(x, planes[::-1], TOL).tolist() == [3.0, 0.75]
    assert collider_crossing(x, planes[::-1], TOL) == (3, 0.75)


def test_a_particle_behind_two_planes_counts_for_each():
    """A particle under the floor and behind the wall (0.5 and 0.625) counts twice; depth 0.625."""
    x = torch.tensor([[1.625, 0.5, -0.5]], dtype=torch.float32)
    _, planes = _scene()
    assert collider_packed(x, planes, TOL).tolist() == [2.0, 0.625]
    assert collider_crossing(x, planes, TOL) == (2, 0.625)


def test_nothing_behind_reads_zero():
    """No particle beyond the tolerance (or no plane): count 0 and depth 0, never a negative depth."""
    x, planes = _scene()
    assert collider_packed(x[[0, 4, 5]], planes, TOL).tolist() == [0.0, 0.0]
    assert collider_packed(x, [], TOL).tolist() == [0.0, 0.0]
    assert collider_crossing(x[[0, 4, 5]], planes, TOL) == (0, 0.0)
