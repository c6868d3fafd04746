"""Pinned rules of the capture loads (`capture.loads`), round three: what each load writes into the config
(gravity, initial velocity, how many crack events and which bands release), where `pull`, `drop` and `impact`
put their grips, floor and kick (hand-computed for a 0.5 × 0.24 × 0.3 m object, Δx = 2 cm), the speed scaling
with the object's size, and the `none` load leaving the config's own settings alone.

Unit-level calls: no simulation.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import LoadPlan, apply_load, plan_load
from fracture_gs.config import CuboidBoundary, ParticleRegion, PlaneBoundary, SceneConfig, SphereBoundary

LO, HI = torch.tensor([0.25, 0.38, 0.35], dtype=torch.float64), torch.tensor([0.75, 0.62, 0.65], dtype=torch.float64)
DX, SIZE, DURATION = 0.02, 0.5, 0.3
G = (0.0, 0.0, -9.8)


def applied(kind: str, speed: float = 0.0) -> SceneConfig:
    """A config whose own settings differ from every load's, with the load `kind` applied."""
    cfg = SceneConfig()
    cfg.sim.gravity = (1.0, 2.0, 3.0)
    cfg.initial_velocity = (0.5, 0.5, 0.5)
    cfg.topology.max_events, cfg.topology.release = 3, "all"
    apply_load(cfg, plan_load(kind, LO, HI, DX, SIZE, speed, DURATION))
    return cfg


@pytest.mark.parametrize(
    "kind, gravity, velocity, events, release",
    [
        ("pull", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1, "first"),
        ("drop", G, (0.0, 0.0, -1.0), 8, "none"),
        ("impact", G, (0.0, 0.0, 0.0), 8, "none"),
        ("shoot", G, (0.0, 0.0, 0.0), 8, "none"),
        ("crush", G, (0.0, 0.0, 0.0), 8, "none"),
    ],
)
def test_each_load_writes_its_gravity_start_velocity_and_events(kind, gravity, velocity, events, release):
    """`pull` is a quasi-static tear: no gravity, at rest, one event whose band releases (`first`); `drop` falls
    under gravity starting at −v (1 m/s at 0.5 m); `impact`, `shoot` and `crush` rest under gravity; those four
    allow up to 8 crack events (the number their note states) and release no band. The config's own gravity,
    start velocity and provider settings are replaced."""
    cfg = applied(kind)
    assert cfg.sim.gravity == gravity
    assert cfg.initial_velocity == velocity
    assert (cfg.topology.max_events, cfg.topology.release) == (events, release)
    note = plan_load(kind, LO, HI, DX, SIZE, 0.0, DURATION).note
    assert (f"up to {events} cracks" in note) == (events > 1), note


def test_the_none_load_keeps_the_configs_own_settings():
    """`none` adds no boundary and changes neither gravity, start velocity nor the provider settings; a plan
    made with no arguments is that: no bodies, no gravity, at rest, one event released `first`, no floor."""
    cfg = applied("none")
    assert cfg.sim.boundaries == [] and cfg.sim.gravity == (1.0, 2.0, 3.0)
    assert cfg.initial_velocity == (0.5, 0.5, 0.5)
    assert (cfg.topology.max_events, cfg.topology.release) == (3, "all")
    p = LoadPlan()
    assert (p.boundaries, p.gravity, p.initial_velocity) == ([], (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert (p.max_events, p.release, p.floor, p.room) == (1, "first", None, None)


def test_pull_grips_hold_the_outer_15_percent_of_each_end():
    """The grips cover x from 2Δx outside each end to 15 % of the length (0.075 m) inside it, y and z with 2Δx to
    spare, and move apart at 0.1 m/s each for the whole run: left (0.21, 0.34, 0.31)–(0.325, 0.66, 0.69) at
    −0.1 m/s, right (0.675, 0.34, 0.31)–(0.79, 0.66, 0.69) at +0.1 m/s."""
    plan = plan_load("pull", LO, HI, DX, SIZE, 0.0, DURATION)
    left, right = plan.boundaries
    assert isinstance(left, CuboidBoundary) and isinstance(right, CuboidBoundary)
    assert left.lower == pytest.approx((0.21, 0.34, 0.31)) and left.upper == pytest.approx((0.325, 0.66, 0.69))
    assert right.lower == pytest.approx((0.675, 0.34, 0.31)) and right.upper == pytest.approx((0.79, 0.66, 0.69))
    assert left.velocity == pytest.approx((-0.1, 0.0, 0.0)) and right.velocity == pytest.approx((0.1, 0.0, 0.0))
    assert left.end == right.end == DURATION
    assert plan.floor is None and plan.room is None


def test_drop_floor_lies_a_fifth_of_the_size_below_the_object():
    """The drop's friction floor (μ = 0.4, normal +z) is 0.2·size = 0.1 m under the object's lowest point (z =
    0.25), which is where the plan's floor is; a given speed of 2 m/s is the start velocity."""
    plan = plan_load("drop", LO, HI, DX, SIZE, 0.0, DURATION)
    (floor,) = plan.boundaries
    assert isinstance(floor, PlaneBoundary) and floor.mode == "friction" and floor.friction == 0.4
    assert floor.point == pytest.approx((0.0, 0.0, 0.25)) and floor.normal == (0.0, 0.0, 1.0)
    assert plan.floor == pytest.approx(0.25)
    assert applied("drop", speed=2.0).initial_velocity == (0.0, 0.0, -2.0)


def test_impact_kicks_the_middle_of_the_minus_x_end_for_5_ms():
    """The impact's floor is 1.5Δx under the object (z = 0.32); the kick region reaches from 2Δx outside the −x
    end to 0.15·size inside it (x 0.21–0.325) and ±0.15·size around the middle of y and z (0.425–0.575 on
    both), and adds 4 m/s along +x from t = 0 to 5 ms."""
    plan = plan_load("impact", LO, HI, DX, SIZE, 0.0, DURATION)
    floor, kick = plan.boundaries
    assert isinstance(floor, PlaneBoundary) and floor.point == pytest.approx((0.0, 0.0, 0.32))
    assert isinstance(kick, ParticleRegion) and kick.kind == "impulse"
    assert kick.lower == pytest.approx((0.21, 0.425, 0.425)) and kick.upper == pytest.approx((0.325, 0.575, 0.575))
    assert kick.delta_v == pytest.approx((4.0, 0.0, 0.0)) and (kick.start, kick.end) == (0.0, 0.005)
    assert plan.floor == pytest.approx(0.32)


@pytest.mark.parametrize("kind, speed", [("pull", 0.1), ("drop", 1.0), ("impact", 4.0), ("shoot", 1.5), ("crush", 0.2)])
def test_automatic_speed_scales_with_the_size(kind, speed):
    """Without capture.load_speed each load moves at its speed for a 0.5 m object times size / 0.5: twice as
    fast for a 1 m object (0.2, 2, 8, 3, 0.4 m/s)."""
    lo, hi = 2 * LO, 2 * HI
    plan = plan_load(kind, lo, hi, DX, 2 * SIZE, 0.0, DURATION)
    v = [b for b in plan.boundaries if not isinstance(b, PlaneBoundary)]
    if kind == "drop":
        assert plan.initial_velocity == pytest.approx((0.0, 0.0, -2 * speed))
        return
    moving = v[0]
    got = moving.delta_v if isinstance(moving, ParticleRegion) else moving.velocity
    assert max(abs(c) for c in got) == pytest.approx(2 * speed)
    if isinstance(moving, SphereBoundary):
        assert moving.velocity == pytest.approx((2 * speed, 0.0, 0.0))
