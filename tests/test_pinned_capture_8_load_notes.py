"""Pinned rule of the load notes (`capture.loads.plan_load`), round eight: the line a capture prints for its load
states what the plan does, with the plan's own numbers: the drop's height is the gap to its floor, 0.2 · size
(0.1 m for a 0.5 m object, 0.2 m at 1 m), its speed the given one or the default scaled with the size; the pull's
grip share and speed; the impact's kick; `none` adds nothing.

The object of round three: [0.25, 0.75] × [0.38, 0.62] × [0.35, 0.65] m, Δx = 2 cm, 0.3 s; doubled for 1 m.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import plan_load

LO, HI = torch.tensor([0.25, 0.38, 0.35], dtype=torch.float64), torch.tensor([0.75, 0.62, 0.65], dtype=torch.float64)
DX, DURATION = 0.02, 0.3


@pytest.mark.parametrize(
    "size, speed, height, v",
    [(0.5, 0.0, "0.1", "1"), (1.0, 0.0, "0.2", "2"), (0.5, 2.5, "0.1", "2.5"), (0.25, 0.0, "0.05", "0.5")],
)
def test_the_drop_note_states_the_fall_height_and_speed(size, speed, height, v):
    """The object falls from 0.2 · size above its floor (the floor's own distance below the object) at the given
    speed, or at 1 m/s · size / 0.5 when none is given."""
    scale = size / 0.5
    plan = plan_load("drop", scale * LO, scale * HI, DX, size, speed, DURATION)
    assert plan.note == f"load drop: falls from {height} m at {v} m/s onto a friction floor (up to 8 cracks)"
    assert float(scale * LO[2]) - plan.floor == pytest.approx(0.2 * size, abs=1e-12)


def test_the_pull_impact_and_none_notes():
    """pull: grips on the outer 15 % of each end, 0.1 m/s apart each by default; impact: a 4 m/s kick at the
    middle of the −x end by default, 3 m/s given; none: only the config's boundaries."""
    pull = plan_load("pull", LO, HI, DX, 0.5, 0.0, DURATION).note
    assert pull == "load pull: grips on the outer 15 % of each end along x, 0.1 m/s apart each, no gravity"
    impact = plan_load("impact", LO, HI, DX, 0.5, 3.0, DURATION).note
    assert impact == (
        "load impact: a 3 m/s kick along +x at the middle of the -x end, resting on a floor (up to 8 cracks)"
    )
    assert "a 4 m/s kick" in plan_load("impact", LO, HI, DX, 0.5, 0.0, DURATION).note
    assert plan_load("none", LO, HI, DX, 0.5, 0.0, DURATION).note == "load none: only the boundaries of the config"
