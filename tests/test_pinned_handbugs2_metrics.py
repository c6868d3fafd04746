"""Hand-written bug campaign, round two: the per-frame metrics (`sim.diagnostics.metrics`) against hand values.

- `plane_state`: with d the signed distance in front of the plane, a fragment touches it when one of its particles
  has d < Δx; the penetration is the deepest −d; the tangential speed is read within Δx (d < Δx) and the normal
  speed within 2Δx (d < 2Δx), each band's edge exclusive.
- `stringing`: ln(s_max / s_min) of F's singular values, the largest over the smallest (not the middle one).
"""

import math

import torch

from fracture_gs.config import PlaneBoundary
from fracture_gs.sim.diagnostics.metrics import plane_state, stringing

DX = 1 / 16


def test_plane_state_reads_each_speed_in_its_own_band():
    """Floor z = 1/4 (normal +z, given with length 2), Δx = 1/16. Particles (fragment 0 unless said) at heights
    d = −1/32 (v = (0, 0, 1/8)), 1/32 (v = (1/2, 0, 0)), 3/32 (fragment 1, v = (1, 0, 1/4)), 5/32 (v = (0, 2, −4)):
    fragment 0 touches (d = −1/32 < Δx), fragment 1 does not (3/32 ≥ Δx); penetration 1/32; the largest tangential
    speed within Δx is 1/2 (the one at 3/32 is outside Δx); the largest normal speed within 2Δx is 1/4 (the one at 5/32
    is outside 2Δx = 4/32)."""
    d = torch.tensor([-1 / 32, 1 / 32, 3 / 32, 5 / 32])
    x = torch.stack([torch.full_like(d, 0.5), torch.full_like(d, 0.5), 0.25 + d], 1)
    v = torch.tensor([[0, 0, 1 / 8], [1 / 2, 0, 0], [1, 0, 1 / 4], [0, 2, -4]], dtype=torch.float32)
    fragment = torch.tensor([0, 0, 1, 0], dtype=torch.int32)
    plane = PlaneBoundary(point=(0.0, 0.0, 0.25), normal=(0.0, 0.0, 2.0))
    out = plane_state(x, v, fragment, plane, DX, 2)
    assert out["touch"].tolist() == [True, False]
    assert float(out["penetration"]) == 1 / 32
    assert float(out["vt_near"]) == 0.5
    assert float(out["vn_close"]) == 0.25


def test_stringing_is_the_log_of_the_largest_over_the_smallest_stretch():
    """Band particles with F = R diag(2, 3/2, 1/2) (R a rotation about z) and diag(1, 1, 1): the mean of ln 4 and 0."""
    c, s = math.cos(0.3), math.sin(0.3)
    R = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    F = torch.stack([R @ torch.diag(torch.tensor([2.0, 1.5, 0.5])), torch.eye(3), torch.eye(3) * 7])
    got = float(stringing(F, torch.tensor([0, 1])))
    assert abs(got - 0.5 * math.log(4.0)) <= 1e-6
