"""`metrics.plane_state` and `metrics.per_fragment_sum`: the fragment–plane numbers of one frame.

Signed distance d = (x − point)·n̂ (the normal normalised). A fragment touches the plane when one of its particles
has d < Δx (strictly: a particle exactly Δx away does not touch); penetration is the deepest −d behind it (0 when
none is behind); vt_near the fastest tangential speed among particles with d < Δx; vn_close the fastest |v·n̂|
among particles with d < 2Δx. Distances below are exact binary fractions, so the strict bounds are tested exactly."""

import torch

from fracture_gs.config import PlaneBoundary
from fracture_gs.sim.diagnostics.metrics import per_fragment_sum, plane_state

DX = 0.25


def _scene():
    """Plane z = 0.5 with an unnormalised normal (0, 0, 2); six particles at chosen heights above it."""
    plane = PlaneBoundary(point=(1.0, 2.0, 0.5), normal=(0.0, 0.0, 2.0))
    z = [0.75, 0.7, 0.25, 1.0, 3.0, 0.5]  # d = 0.25 (= Δx), 0.2, −0.25, 0.5 (= 2Δx), 2.5, 0
    x = torch.tensor([[0.3, -0.2, zz] for zz in z], dtype=torch.float32)
    v = torch.tensor(
        [[3.0, 0.0, -1.0], [0.0, 2.0, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, -7.0], [10.0, 0.0, 9.0], [0.0, 0.0, 0.0]],
        dtype=torch.float32,
    )
    fragment = torch.tensor([0, 1, 2, 0, 3, -1], dtype=torch.int32)
    return x, v, fragment, plane


def test_touch_is_strictly_within_one_cell_per_fragment():
    """Fragment 0's particles lie exactly Δx and 2Δx away: it does not touch; fragment 1 (0.2 away) and 2 (behind)
    do; fragment 3 (far) does not; an unlabelled particle on the plane touches no fragment."""
    x, v, fragment, plane = _scene()
    out = plane_state(x, v, fragment, plane, DX, 4)
    assert out["touch"].tolist() == [False, True, True, False]


def test_speeds_near_the_plane_use_their_own_strict_bands():
    """vt_near: the particle exactly Δx away (tangential speed 3) is outside, so the fastest near one is fragment
    1's (2); vn_close: the particle exactly 2Δx away (normal speed 7) is outside, the one at Δx (normal speed 1)
    is inside; the far particle's speeds (10, 9) count in neither."""
    x, v, fragment, plane = _scene()
    out = plane_state(x, v, fragment, plane, DX, 4)
    assert float(out["vt_near"]) == 2.0
    assert float(out["vn_close"]) == 1.0


def test_penetration_is_the_deepest_distance_behind_the_plane():
    """One particle 0.25 behind the plane: penetration 0.25; lift it above and the penetration is 0, not negative."""
    x, v, fragment, plane = _scene()
    assert float(plane_state(x, v, fragment, plane, DX, 4)["penetration"]) == 0.25
    x[2, 2] = 0.625
    assert float(plane_state(x, v, fragment, plane, DX, 4)["penetration"]) == 0.0


def test_per_fragment_sum_adds_each_fragments_values_and_skips_ids_outside_the_range():
    """Σ per fragment id in [0, K): ids −1 and K are left out (not clamped into the first or last bin)."""
    values = torch.tensor([1.0, 2.0, 4.0, 8.0, 16.0, 32.0], dtype=torch.float64)
    fragment = torch.tensor([0, 2, 0, -1, 3, 2])
    assert per_fragment_sum(values, fragment, 3).tolist() == [5.0, 0.0, 34.0]
