"""Pinned rules of the ground split (`capture.scene._above_ground`), round six: which Gaussians are the object's
side of the ground and which stay a static background.

- a Gaussian is above the ground when its height along the *unit* up direction is strictly above
  capture.ground_level: the up vector's length does not scale the heights (the ground finder measures along the
  unit vector too, so a level it finds splits the scene where it found it);
- with no level (ground = "none", or "auto" finding no flat layer) everything is above, no note is written, and
  "auto" that finds nothing becomes "none" so the written config repeats the run;
- the note counts the Gaussians kept as background and states the level.

Hand-built point sets; nothing is read or simulated.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.ground import find_ground
from fracture_gs.capture.scene import _above_ground
from fracture_gs.config import CaptureConfig

F64 = torch.float64


def column(heights, up) -> torch.Tensor:  # [n, 3]: points at the given heights along up, off-axis by a fixed offset
    u = torch.tensor(up, dtype=F64)
    u = u / u.norm()
    side = torch.linalg.cross(u, torch.tensor([1.0, 0.0, 0.0], dtype=F64))
    side = side / side.norm()  # a direction at right angles to up: moving along it changes no height
    h = torch.tensor(heights, dtype=F64)[:, None]
    return h * u + 0.7 * side


@pytest.mark.parametrize("up", [(0.0, 0.0, 2.0), (0.0, 3.0, 4.0), (0.0, -0.25, 0.0)])
def test_heights_are_measured_along_the_unit_up_direction_whatever_its_length(up):
    """Points at heights 0, 0.1, 0.2, 0.3 and 0.5 along up (given with length 2, 5 or 0.25), level 0.2: the
    first three (0.2 itself included: above means strictly above) are ground, the last two are above. The note
    counts the 3 ground Gaussians and gives the level."""
    cap = CaptureConfig(ground="auto", ground_level=0.2)
    notes: list = []
    above = _above_ground(
        column([0.0, 0.1, 0.2 - 1e-12, 0.2 + 1e-12, 0.5], up), torch.tensor(up, dtype=F64), cap, notes
    )
    assert above.tolist() == [False, False, False, True, True]
    assert notes == [
        "ground: a flat layer under the object (3 Gaussians up to 0.2 along the up axis) is kept as a static "
        'background and the floor stands on it (capture.ground = "none" keeps it)'
    ]
    assert cap.ground_level == 0.2 and cap.ground == "auto", "a level given is used as written"


def test_a_gaussian_exactly_at_the_level_is_ground():
    """Above means strictly above: with up (0, 0, 4) and level 0.25, a Gaussian at z = 0.25 exactly (0.25 · 4 / 4
    has no round-off) is ground, one at 0.2500001 above."""
    means = torch.tensor([[0.3, 0.1, 0.25], [0.3, 0.1, 0.2500001]], dtype=F64)
    above = _above_ground(means, torch.tensor([0.0, 0.0, 4.0], dtype=F64), CaptureConfig(ground_level=0.25), [])
    assert above.tolist() == [False, True]


def test_a_level_found_along_a_long_up_vector_splits_the_scene_where_it_was_found():
    """A pavement (a thin wide layer, 3000 Gaussians at heights 0–0.01) under a block (1000 Gaussians at heights
    0.3–0.6), up given as (0, 0, 3): `ground = "auto"` finds the pavement's top and records it, and the split
    keeps exactly the pavement as background, the same as with the unit up (0, 0, 1)."""
    g = torch.Generator().manual_seed(3)
    pave = torch.cat(
        [(torch.rand(3000, 2, generator=g, dtype=F64) * 2 - 1), 0.01 * torch.rand(3000, 1, generator=g, dtype=F64)], 1
    )
    block = torch.rand(1000, 3, generator=g, dtype=F64) * torch.tensor([0.3, 0.3, 0.3], dtype=F64)
    block[:, 2] += 0.3
    means = torch.cat([pave, block])
    splits = []
    for up in ((0.0, 0.0, 3.0), (0.0, 0.0, 1.0)):
        cap, notes = CaptureConfig(ground="auto"), []
        above = _above_ground(means, torch.tensor(up, dtype=F64), cap, notes)
        assert cap.ground_level == find_ground(means, torch.tensor(up, dtype=F64)) and cap.ground_level is not None
        assert 0.01 <= cap.ground_level < 0.3, cap.ground_level
        assert above.tolist() == [False] * 3000 + [True] * 1000
        assert notes[0].startswith("ground: a flat layer under the object (3000 Gaussians up to "), notes
        splits.append(above)
    assert torch.equal(splits[0], splits[1])


@pytest.mark.parametrize("ground", ["auto", "none"])
def test_without_a_level_every_gaussian_is_above_and_nothing_is_noted(ground):
    """A cloud with no flat layer under it (uniform in a cube) and ground = "auto" finds no ground: it becomes
    "none", every Gaussian is above and no note is written; ground = "none" with no level is the same."""
    g = torch.Generator().manual_seed(5)
    means = torch.rand(2000, 3, generator=g, dtype=F64)
    cap, notes = CaptureConfig(ground=ground), []
    if ground == "auto":
        assert find_ground(means, torch.tensor([0.0, 0.0, 1.0], dtype=F64)) is None
    above = _above_ground(means, torch.tensor([0.0, 0.0, 5.0], dtype=F64), cap, notes)
    assert above.dtype == torch.bool and bool(above.all()) and len(above) == 2000
    assert notes == [] and cap.ground == "none" and cap.ground_level is None
