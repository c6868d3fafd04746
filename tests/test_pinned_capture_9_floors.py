"""Pinned rule of the floors the capture loads put under an object (`capture.loads.plan_load`), round nine:
every load that rests or lands the object on a floor (`drop`, `impact`, `shoot`, `crush`) writes one horizontal
friction plane (unit normal +z, pointing up into the free side, Coulomb μ = 0.4) and reports its height as
`plan.floor`; `drop`'s floor lies 0.2·size under the object, `impact`'s 1.5Δx under it, and `shoot`'s and
`crush`'s Δx/2 under it (resting). `pull` and `none` have no floor.

Hand-computed for an object at (0.25, 0.38, 0.35)–(0.75, 0.62, 0.65), size 0.5 m, Δx = 2 cm. Unit-level calls.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import plan_load
from fracture_gs.config import PlaneBoundary

LO, HI = torch.tensor([0.25, 0.38, 0.35], dtype=torch.float64), torch.tensor([0.75, 0.62, 0.65], dtype=torch.float64)
DX, SIZE, DURATION = 0.02, 0.5, 0.3


@pytest.mark.parametrize("kind, z", [("drop", 0.25), ("impact", 0.32), ("shoot", 0.34), ("crush", 0.34)])
def test_each_resting_or_landing_load_has_one_level_friction_floor(kind, z):
    """drop: 0.35 − 0.2·0.5 = 0.25; impact: 0.35 − 1.5·0.02 = 0.32; shoot and crush: 0.35 − 0.02/2 = 0.34. The
    plane is exactly level with a unit normal along +z (a tilted or longer normal would slide the pieces sideways
    or scale the contact response), friction mode with μ = 0.4, and plan.floor is its height."""
    plan = plan_load(kind, LO, HI, DX, SIZE, 0.0, DURATION)
    floors = [b for b in plan.boundaries if isinstance(b, PlaneBoundary)]
    assert len(floors) == 1
    (floor,) = floors
    assert floor.normal == (0.0, 0.0, 1.0)
    assert floor.point[:2] == (0.0, 0.0) and floor.point[2] == pytest.approx(z, abs=1e-12)
    assert (floor.mode, floor.friction) == ("friction", 0.4)
    assert plan.floor == pytest.approx(z, abs=1e-12)


@pytest.mark.parametrize("kind", ["pull", "none"])
def test_pull_and_none_have_no_floor(kind):
    """pull hangs the object between its grips with no gravity and none adds nothing: no plane, no floor."""
    plan = plan_load(kind, LO, HI, DX, SIZE, 0.0, DURATION)
    assert not any(isinstance(b, PlaneBoundary) for b in plan.boundaries)
    assert plan.floor is None


def test_the_impact_floor_follows_the_cell_size_not_the_object_size():
    """impact's floor is 1.5Δx under the object whatever its size: Δx = 5 cm puts it at 0.35 − 0.075 = 0.275,
    and doubling the size does not move it."""
    for size in (0.5, 1.0):
        plan = plan_load("impact", LO, HI, 0.05, size, 0.0, DURATION)
        assert plan.floor == pytest.approx(0.275, abs=1e-12)
        assert plan.boundaries[0].point[2] == pytest.approx(0.275, abs=1e-12)
