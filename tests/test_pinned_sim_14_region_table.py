"""The host side of the boundaries (`sim.physics.boundary.Boundaries`), against hand values:

- a velocity region is on in every substep that starts in [start, end + Δt/2] (both ends included: a window
  ending half a substep before a substep's start still covers it), with its velocity as the value;
- an impulse shorter than a substep (or of zero length) is spread over one substep, Δt: it is on in the one
  substep starting in [start, start + Δt) and gives its whole Δv there;
- the plane normals and the pushers' directions are stored as unit vectors (a sticky box's zero push stays zero);
- an unknown entry, plane mode or region kind is refused with one sentence naming it and the choices.

Δt = 2⁻¹⁰ s and window ends on multiples of Δt/4: every comparison is exact."""

import pytest
import torch

from fracture_gs.config import CuboidBoundary, ParticleRegion, PlaneBoundary
from fracture_gs.errors import SimulationError
from fracture_gs.sim.physics.boundary import Boundaries

DT = 2.0**-10
TIMES = [k * DT for k in range(12)]


def _on(region):
    on, value = Boundaries([region], "cpu").region_table(TIMES, DT)
    return [k for k in range(12) if on[k]], value


@pytest.mark.parametrize("end, steps", [(8.0, [4, 5, 6, 7, 8]), (7.5, [4, 5, 6, 7, 8]), (7.25, [4, 5, 6, 7])])
def test_a_velocity_region_covers_the_substeps_starting_up_to_half_a_step_after_its_end(end, steps):
    """Velocity (1, −2, 0.5) from 4Δt to end: on in the substeps starting in [4Δt, end + Δt/2], with that velocity."""
    got, value = _on(ParticleRegion(kind="velocity", velocity=(1.0, -2.0, 0.5), start=4 * DT, end=end * DT))
    assert got == steps
    assert all(value[k] == [1.0, -2.0, 0.5] for k in steps)


@pytest.mark.parametrize("start, end, step", [(4.0, 4.0, 4), (4.0, 4.25, 4), (3.5, 3.75, 4), (3.0, 3.75, 3)])
def test_an_impulse_shorter_than_a_substep_is_given_whole_in_one_substep(start, end, step):
    """Δv = (0, 0, 3) over [start, end] with end − start < Δt: one substep (the one starting in [start, start + Δt))
    is on and carries all of Δv."""
    got, value = _on(ParticleRegion(kind="impulse", delta_v=(0.0, 0.0, 3.0), start=start * DT, end=end * DT))
    assert got == [step]
    assert value[step] == [0.0, 0.0, 3.0]


def test_directions_are_stored_as_unit_vectors():
    """A plane normal (0, 0, 2) is stored (0, 0, 1), a pusher (3, 0, 4) as (0.6, 0, 0.8), a sticky box's (0, 0, 0)
    stays (0, 0, 0); the plane's mode and friction go along as id and μ."""
    items = [
        PlaneBoundary(point=(0.0, 0.0, 0.25), normal=(0.0, 0.0, 2.0), mode="friction", friction=0.5),
        CuboidBoundary(upper=(1.0, 1.0, 1.0), push=(3.0, 0.0, 4.0)),
        CuboidBoundary(upper=(1.0, 1.0, 1.0)),
    ]
    t = Boundaries(items, "cpu").t
    assert t["plane_normal"].tolist() == [[0.0, 0.0, 1.0]]
    torch.testing.assert_close(t["box_push"], torch.tensor([[0.6, 0.0, 0.8], [0.0, 0.0, 0.0]]))
    assert t["plane_mode"].tolist() == [2] and t["plane_mu"].tolist() == [0.5]
    assert t["box_time"].tolist() == [[0.0, float(torch.tensor(1e30))]] * 2  # float32: 1e30 stays finite


def test_unknown_entries_modes_and_kinds_are_refused_by_name():
    """A string among the boundaries, a plane mode 'glue' and a region kind 'teleport' each raise one sentence that
    names the value and the choices."""
    with pytest.raises(SimulationError, match=r"^sim.boundaries: unsupported entry 'wall'; use PlaneBoundary, "):
        Boundaries(["wall"], "cpu")
    with pytest.raises(SimulationError, match=r"plane mode 'glue' is not one of \['friction', 'slip', 'sticky'\]$"):
        Boundaries([PlaneBoundary(mode="glue")], "cpu")
    b = Boundaries([ParticleRegion(kind="teleport")], "cpu")
    with pytest.raises(SimulationError, match=r"region kind 'teleport' is not 'impulse' or 'velocity'$"):
        b.region_table([0.0], DT)
