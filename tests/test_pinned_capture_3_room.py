"""Pinned rules of the room a captured scene's grid must hold (`capture.scene._room`), round three: the object's
box with a 0.1·size margin; along x, as far as the fastest boundary moves in the run (at most half the size);
with a floor, down to 0.05·size under it and 0.2·size wider in x and y for the pieces; and the corners the
load's own bodies sweep, with the same margin on both sides.

Hand-computed boxes for a 0.5 m object at (0.25, 0.38, 0.35)–(0.75, 0.62, 0.65): margin 0.05 m.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import LoadPlan
from fracture_gs.capture.scene import _room
from fracture_gs.config import CuboidBoundary, ParticleRegion

SIZE = 0.5


def box():
    return torch.tensor([0.25, 0.38, 0.35], dtype=torch.float64), torch.tensor([0.75, 0.62, 0.65], dtype=torch.float64)


def room(plan: LoadPlan, duration: float = 0.3):
    lo, hi = box()
    room_lo, room_hi = _room(SIZE, lo, hi, plan, duration)
    assert torch.equal(lo, box()[0]) and torch.equal(hi, box()[1]), "the object's box is not changed"
    return room_lo.tolist(), room_hi.tolist()


def test_a_still_load_needs_the_object_and_its_margin():
    """No boundaries, no floor, no bodies: the object's box grown by 0.1·size = 0.05 m on every side."""
    lo, hi = room(LoadPlan())
    assert lo == pytest.approx([0.2, 0.33, 0.3]) and hi == pytest.approx([0.8, 0.67, 0.7])


@pytest.mark.parametrize(
    "speed, duration, travel",
    [(0.1, 0.3, 0.03), (-0.4, 0.3, 0.12), (10.0, 0.3, 0.25)],
)
def test_moving_boundaries_widen_the_room_along_x_by_their_travel(speed, duration, travel):
    """The room grows on both x sides by the fastest boundary's |v|·duration (a grip at 0.1 m/s for 0.3 s: 3 cm;
    −0.4 m/s: 12 cm), capped at half the size (25 cm); y and z keep the margin."""
    grip = CuboidBoundary(lower=(0.0, 0.0, 0.0), upper=(0.1, 0.1, 0.1), velocity=(speed, 0.0, 0.0))
    lo, hi = room(LoadPlan(boundaries=[grip]), duration)
    assert lo == pytest.approx([0.2 - travel, 0.33, 0.3]) and hi == pytest.approx([0.8 + travel, 0.67, 0.7])


def test_a_kick_counts_as_travel_by_its_velocity_change():
    """A particle region's Δv counts like a boundary's velocity: a 4 m/s kick over a 0.01 s run travels 4 cm."""
    kick = ParticleRegion(kind="impulse", lower=(0.0, 0.0, 0.0), upper=(0.1, 0.1, 0.1), delta_v=(0.0, -4.0, 0.0))
    lo, hi = room(LoadPlan(boundaries=[kick]), 0.01)
    assert lo == pytest.approx([0.16, 0.33, 0.3]) and hi == pytest.approx([0.84, 0.67, 0.7])


@pytest.mark.parametrize("floor, z_lo", [(0.25, 0.225), (0.4, 0.3)])
def test_a_floor_is_held_with_room_for_the_pieces(floor, z_lo):
    """With a floor at z = 0.25 the room reaches 0.05·size = 2.5 cm under it (z 0.225); a floor above the margin
    (0.4) keeps the object's margin (z 0.3); either way x and y grow by 0.2·size = 0.1 m on both sides."""
    lo, hi = room(LoadPlan(floor=floor))
    assert lo == pytest.approx([0.1, 0.23, z_lo]) and hi == pytest.approx([0.9, 0.77, 0.7])


def test_the_loads_own_bodies_are_held_with_the_margin():
    """A body sweeping (0, 0.45, 0.5)–(0.6, 0.55, 0.9) (a ball's path starting left of the object, a plate above
    it) extends the room to its lower corner minus the margin where that is lower (x −0.05) and its upper
    corner plus the margin where that is higher (z 0.95); elsewhere the object's margin stands."""
    lo, hi = room(LoadPlan(room=((0.0, 0.45, 0.5), (0.6, 0.55, 0.9))))
    assert lo == pytest.approx([-0.05, 0.33, 0.3]) and hi == pytest.approx([0.8, 0.67, 0.95])
    lo, hi = room(LoadPlan(room=((0.3, 0.1, 0.4), (1.2, 0.5, 0.5))))
    assert lo == pytest.approx([0.2, 0.05, 0.3]) and hi == pytest.approx([1.25, 0.67, 0.7])
