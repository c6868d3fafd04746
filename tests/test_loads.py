"""The `shoot` and `crush` loads of a captured object (`capture/loads.py`): where `plan_load` puts the ball
and the plate around the object, that the resolved scene's grid holds their paths, that a block under the
crush plate is pressed down with it and stays put once the plate stops, and that `--load` offers them."""

from __future__ import annotations

import pytest
import torch
from simutil import block, config, particles
from trainer_ply import write_trainer_ply

from fracture_gs import sim as S
from fracture_gs.capture.loads import plan_load
from fracture_gs.capture.scene import resolve
from fracture_gs.cli.parser import build_parser
from fracture_gs.config import CuboidBoundary, PlaneBoundary, SphereBoundary
from fracture_gs.io.config import load_config

pytestmark = pytest.mark.usefixtures("one_thread")

LO, HI = torch.tensor([0.25, 0.38, 0.35]), torch.tensor([0.75, 0.62, 0.65])  # a 0.5 × 0.24 × 0.3 m object
DX, SIZE, DURATION = 0.5 / 24, 0.5, 0.3


def of_type(plan, cls):
    return [b for b in plan.boundaries if type(b) is cls]


@pytest.mark.parametrize("size", [0.5, 1.0])
def test_shoot_places_a_ball_outside_the_object_on_a_path_through_it(size):
    """The ball (radius 0.12·size) starts clear of the object's box on its −x side, at the middle of its y and
    z extents, flies along +x at 1.5 m/s·size/0.5 (or capture.load_speed) and switches off only once it is past
    the object's +x end; the object rests on a friction floor under gravity, up to 8 events."""
    lo, hi = LO * size / 0.5, HI * size / 0.5
    plan = plan_load("shoot", lo, hi, DX, size, 0.0, DURATION)
    (ball,) = of_type(plan, SphereBoundary)
    (floor,) = of_type(plan, PlaneBoundary)
    c, r = torch.tensor(ball.center), ball.radius
    assert r == pytest.approx(0.12 * size)
    assert float((torch.maximum(lo - c, torch.zeros(3)) + torch.maximum(c - hi, torch.zeros(3))).norm()) > r
    assert float(c[0]) < float(lo[0]) and torch.allclose(c[1:], 0.5 * (lo[1:] + hi[1:]))
    assert ball.velocity == pytest.approx((1.5 * size / 0.5, 0.0, 0.0))
    assert float(c[0]) + ball.velocity[0] * ball.end - r > float(hi[0]), "it ends past the far end"
    assert ball.start == 0.0 and floor.mode == "friction" and floor.point[2] < float(lo[2])
    assert plan.gravity[2] < 0 and plan.max_events == 8 and plan.floor == floor.point[2]
    assert "ball" in plan.note and "+x" in plan.note
    fast = plan_load("shoot", lo, hi, DX, size, 5.0, DURATION)
    assert of_type(fast, SphereBoundary)[0].velocity[0] == 5.0


def test_crush_places_a_plate_over_the_object_that_stops_above_the_floor():
    """The plate lies on the object's top, covers its x–y footprint with a margin, moves down at 0.2 m/s (at
    size 0.5 m), pushes without holding (push = −z), and at its end time its lower face is 25 % of the
    object's height above the floor, where a still plate takes over until the end of the run."""
    plan = plan_load("crush", LO, HI, DX, SIZE, 0.0, DURATION)
    press, held = of_type(plan, CuboidBoundary)
    (floor,) = of_type(plan, PlaneBoundary)
    lower, upper = torch.tensor(press.lower), torch.tensor(press.upper)
    assert float(lower[2]) >= float(HI[2]) and float(lower[2]) - float(HI[2]) < DX
    assert bool((lower[:2] < LO[:2]).all()) and bool((upper[:2] > HI[:2]).all())
    assert press.velocity == pytest.approx((0.0, 0.0, -0.2)) and press.push == (0.0, 0.0, -1.0)
    face_at_end = press.lower[2] + press.velocity[2] * press.end
    height = float(HI[2] - LO[2])
    assert face_at_end == pytest.approx(floor.point[2] + 0.25 * height)
    assert held.start == press.end and held.velocity == (0.0, 0.0, 0.0) and held.push == press.push
    assert held.lower[2] == pytest.approx(face_at_end) and held.end > 1e29
    assert plan.gravity[2] < 0 and plan.max_events == 8 and "would stop" in plan.note  # 1.2 s, after the run


@pytest.mark.slow
def test_the_grid_holds_the_ball_path_and_the_plate(tmp_path):
    """A captured scene resolved with each load: the explicit grid, inside its walls, holds the ball where it
    starts and where it is at the end of the run, and the plate where it starts above the object. The ball is
    slow (0.2 m/s), so the room the load's speed makes along x alone would not reach its start."""
    ply, _ = write_trainer_ply(tmp_path, n=3000)
    for load in ("shoot", "crush"):
        cfg = load_config(ply)
        cfg.capture.cells_across, cfg.capture.max_particles, cfg.capture.load = 16, 3000, load
        cfg.capture.load_speed = 0.2
        s = resolve(cfg).cfg.sim
        inner_lo = torch.tensor(s.grid_origin) + s.wall_cells * s.dx
        inner_hi = torch.tensor(s.grid_origin) + (torch.tensor(s.grid_shape) - 1 - s.wall_cells) * s.dx
        boxes = []
        for b in s.boundaries:
            if isinstance(b, SphereBoundary):
                c, v = torch.tensor(b.center), torch.tensor(b.velocity)
                for t in (0.0, min(b.end, cfg.frames * cfg.frame_dt)):
                    boxes.append((c + v * t - b.radius, c + v * t + b.radius))
            elif isinstance(b, CuboidBoundary):
                boxes.append((torch.tensor(b.lower), torch.tensor(b.upper)))
        assert len(boxes) == 2, load
        for lo, hi in boxes:
            assert bool((lo >= inner_lo - 1e-6).all() and (hi <= inner_hi + 1e-6).all()), (load, lo, hi, inner_hi)


def test_a_block_under_the_crush_plate_is_pressed_down_and_held():
    """A 9.4 cm tall block on the plan's floor, the plate pressing at 1 m/s (gravity on): while it moves, the
    top of the block's middle follows the plate's face within half a cell; by the end time the block is lower
    by about the plate's travel (within 2Δx: the plate starts Δx/2 above it and the block settles on the floor);
    afterwards the plate stands still and so does the block's top (no spring-back, no further descent)."""
    dx = 1 / 32
    x, vol = block((0.35, 0.4, 0.2), (0.65, 0.6, 0.3125), 1 / 64)
    lo, hi = x.min(0).values, x.max(0).values
    plan = plan_load("crush", lo, hi, dx, 0.3, 1.0, 0.3)
    press = of_type(plan, CuboidBoundary)[0]
    cfg = config(32, dt=2e-3, adaptive_dt=True, boundaries=plan.boundaries, gravity=plan.gravity)
    sim = S.Simulator(cfg, particles(x, vol, rho=500.0, E=2e4, nu=0.3), device="cpu")
    middle = ((x[:, 0] - 0.5).abs() < 0.05) & ((x[:, 1] - 0.5).abs() < 0.05)
    height0 = float(hi[2] - lo[2])
    tops, heights, times = [], [], []
    for f in range(20):
        sim.advance(0.01)
        z = sim.particles.x[middle, 2]
        tops.append(float(z.max()))
        heights.append(float(z.max() - z.min()))
        times.append((f + 1) * 0.01)
    for t, top in zip(times, tops):
        if t <= press.end:
            face = press.lower[2] + press.velocity[2] * t
            assert abs(top - face) <= 0.5 * dx, f"t = {t:.2f}: top {top:.4f} against the plate at {face:.4f}"
    travel = -press.velocity[2] * press.end
    at_end = next(h for t, h in zip(times, heights) if t >= press.end)
    assert travel - 2 * dx <= height0 - at_end <= travel, (height0 - at_end, travel)
    after = [top for t, top in zip(times, tops) if t >= press.end + 0.01]
    assert len(after) >= 5 and max(after) - min(after) < 0.1 * dx, after


def test_cli_offers_the_new_loads():
    """`render-sim --load` and `init --load` take their choices from capture.load's Literal: shoot and crush
    parse, a misspelt load does not."""
    parser = build_parser()
    for load in ("shoot", "crush"):
        assert parser.parse_args(["render-sim", "scan.ply", "--load", load]).load == load
        assert parser.parse_args(["init", "scan.ply", "--load", load]).load == load
    with pytest.raises(Exception, match="invalid choice"):
        parser.parse_args(["render-sim", "scan.ply", "--load", "shot"])
