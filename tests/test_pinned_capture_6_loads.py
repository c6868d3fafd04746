"""Pinned geometry of the `shoot` and `crush` loads (`capture.loads._shoot` / `_crush`), round six: every corner,
centre, time and note number hand-computed for an object whose six box coordinates all differ, so a coordinate
read from the wrong axis (x for y, z for x, ...) moves a number the test checks.

The object: [0.2, 0.4, 0.1]–[0.7, 0.6, 0.4] m (0.5 × 0.2 × 0.3 m), Δx = 2 cm, size 0.5 m.

- both loads stand it on a friction floor (μ = 0.4, normal +z) Δx/2 under its lowest point: z = 0.09;
- shoot: a ball of radius 0.12·size = 0.06 centred 2Δx + r clear of the −x face, at the middle of y and z:
  (0.10, 0.5, 0.25); at 1.5 m/s it switches off 2Δx + r past the +x face, at t = (0.80 − 0.10) / 1.5 = 0.4667 s;
  the room it needs is its path up to min(end, run) widened by r;
- crush: a 3Δx plate over the footprint plus 0.1·size = 0.05 on x and y, its lower face Δx/2 above the top
  (0.41), moving down at 0.2 m/s until that face is 25 % of the height (0.075) above the floor, z = 0.165,
  at t = (0.41 − 0.165) / 0.2 = 1.225 s; then a still plate holds it there.

Unit-level calls: no simulation.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import plan_load
from fracture_gs.config import CuboidBoundary, PlaneBoundary, SphereBoundary

LO = torch.tensor([0.2, 0.4, 0.1], dtype=torch.float64)
HI = torch.tensor([0.7, 0.6, 0.4], dtype=torch.float64)
DX, SIZE = 0.02, 0.5
FLOOR_Z = 0.09


def _floor_ok(floor) -> None:
    assert isinstance(floor, PlaneBoundary)
    assert floor.point == pytest.approx((0.0, 0.0, FLOOR_Z)) and floor.normal == (0.0, 0.0, 1.0)
    assert (floor.mode, floor.friction) == ("friction", 0.4)


@pytest.mark.parametrize("duration, reach", [(0.3, 0.55), (1.0, 0.80)])
def test_the_shoot_ball_starts_clear_of_the_minus_x_face_and_flies_past_the_far_end(duration, reach):
    """The ball (r = 0.06) is centred at (0.10, 0.5, 0.25): 2Δx + r before the −x face at x = 0.2, at the middle
    of y (0.4–0.6) and z (0.1–0.4). At 1.5 m/s it is on from t = 0 to 0.4667 s, when its centre is 2Δx + r past
    the +x face (0.80). The room it needs spans its path up to min(end, run), widened by r on every side:
    reach 0.55 in a 0.3 s run, 0.80 (the end) in a 1 s run."""
    plan = plan_load("shoot", LO, HI, DX, SIZE, 0.0, duration)
    floor, ball = plan.boundaries
    _floor_ok(floor)
    assert isinstance(ball, SphereBoundary)
    assert ball.radius == pytest.approx(0.06)
    assert ball.center == pytest.approx((0.10, 0.5, 0.25))
    assert ball.velocity == pytest.approx((1.5, 0.0, 0.0))
    assert ball.start == 0.0 and ball.end == pytest.approx(0.7 / 1.5)
    lower, upper = plan.room
    assert lower == pytest.approx((0.04, 0.44, 0.19)) and upper == pytest.approx((reach + 0.06, 0.56, 0.31))
    assert plan.floor == pytest.approx(FLOOR_Z)
    assert (plan.gravity, plan.max_events, plan.release) == ((0.0, 0.0, -9.8), 8, "none")
    assert "radius 0.06 m" in plan.note and "at 1.5 m/s" in plan.note and "by t = 0.467 s" in plan.note, plan.note


def test_a_given_shoot_speed_sets_the_ball_speed_and_its_end_time():
    """capture.load_speed = 3.5 m/s flies the ball at 3.5 m/s: it crosses the same 0.70 m in 0.2 s, which the
    note states; its start and radius do not depend on the speed."""
    plan = plan_load("shoot", LO, HI, DX, SIZE, 3.5, 0.3)
    ball = plan.boundaries[1]
    assert ball.velocity == pytest.approx((3.5, 0.0, 0.0)) and ball.end == pytest.approx(0.2)
    assert ball.center == pytest.approx((0.10, 0.5, 0.25)) and ball.radius == pytest.approx(0.06)
    assert plan.room[1][0] == pytest.approx(0.86)  # it reaches 0.80 at t = 0.2 s, before the run's end
    assert "at 3.5 m/s" in plan.note and "by t = 0.2 s" in plan.note, plan.note


def test_the_crush_plate_covers_the_footprint_and_is_held_at_a_quarter_of_the_height():
    """The pressing plate spans x 0.15–0.75 and y 0.35–0.65 (the footprint plus 0.05), z 0.41–0.47 (3Δx from
    Δx/2 above the top); it moves down at 0.2 m/s from t = 0 until 1.225 s, when its face is at z = 0.165, 25 %
    of the 0.3 m height above the floor at 0.09; from then a still plate of the same footprint and thickness
    holds that face, for the rest of any run. Both push along −z only. The room is the pressing plate's box."""
    plan = plan_load("crush", LO, HI, DX, SIZE, 0.0, 0.3)
    floor, press, held = plan.boundaries
    _floor_ok(floor)
    assert isinstance(press, CuboidBoundary) and isinstance(held, CuboidBoundary)
    assert press.lower == pytest.approx((0.15, 0.35, 0.41)) and press.upper == pytest.approx((0.75, 0.65, 0.47))
    assert press.velocity == pytest.approx((0.0, 0.0, -0.2)) and press.push == (0.0, 0.0, -1.0)
    assert press.start == 0.0 and press.end == pytest.approx(1.225)
    assert held.lower == pytest.approx((0.15, 0.35, 0.165)) and held.upper == pytest.approx((0.75, 0.65, 0.225))
    assert held.velocity == (0.0, 0.0, 0.0) and held.push == (0.0, 0.0, -1.0)
    assert held.start == pytest.approx(1.225) and held.end > 1e29
    lower, upper = plan.room
    assert lower == pytest.approx((0.15, 0.35, 0.41)) and upper == pytest.approx((0.75, 0.65, 0.47))
    assert plan.floor == pytest.approx(FLOOR_Z)
    assert (plan.gravity, plan.max_events, plan.release) == ((0.0, 0.0, -9.8), 8, "none")


@pytest.mark.parametrize(
    "duration, what",
    [
        (0.3, "0.06 m in this run, it would stop 0.075 m above the floor (25 % of the object's height) at t = 1.22 s"),
        (None, "it stops 0.075 m above the floor (25 % of the object's height) at t = 1.22 s and stays"),
        (2.0, "it stops 0.075 m above the floor (25 % of the object's height) at t = 1.22 s and stays"),
    ],
)
def test_the_crush_note_says_where_the_plate_stops_above_the_floor_and_when(duration, what):
    """The note measures the stop from the floor (0.165 − 0.09 = 0.075 m, not from z = 0), gives the stop time,
    and says whether the plate gets there in the run: in a 0.3 s run it moves 0.2 × 0.3 = 0.06 m and would
    stop later; a run exactly as long as the stop time (None: the plan's own end time) or longer sees it stop
    and stay."""
    if duration is None:
        duration = plan_load("crush", LO, HI, DX, SIZE, 0.0, 0.3).boundaries[1].end
    plan = plan_load("crush", LO, HI, DX, SIZE, 0.0, duration)
    want = (
        "load crush: a plate over the whole top presses down at 0.2 m/s on the object, which rests on a friction "
        f"floor: {what} (up to 8 cracks)"
    )
    assert plan.note == want


def test_crush_speed_follows_the_size_and_a_given_speed():
    """Without capture.load_speed the plate moves at 0.2 m/s · size / 0.5 (0.4 m/s for a 1 m object, so it
    stops at half the time); a given 0.49 m/s is used as written (end 0.245 / 0.49 = 0.5 s)."""
    auto = plan_load("crush", LO, HI, DX, 1.0, 0.0, 0.3).boundaries[1]
    assert auto.velocity == pytest.approx((0.0, 0.0, -0.4))
    given = plan_load("crush", LO, HI, DX, SIZE, 0.49, 0.3).boundaries[1]
    assert given.velocity == pytest.approx((0.0, 0.0, -0.49)) and given.end == pytest.approx(0.5)
