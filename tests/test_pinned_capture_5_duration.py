"""Pinned rule of a resolved capture's load (`capture.scene.resolve`), round five: the load acts for the whole
run, frames × frame_dt seconds. A pull's grips move until then (their `end`), the grid's room along x grows by
how far they travel in that time (|v|·frames·frame_dt, at most half the size), and a crush plate too slow to
reach its stop says how far it gets in the run.

A small trainer-like capture (300 surface Gaussians, no floaters) resolved at 8 cells across, no interior fill:
about a quarter of a second. The fitted object is 0.5 m long along x, centred at x = 0.5: x from 0.25 to 0.75;
Δx = 0.5 / 8 = 0.0625 m; the capture config's walls are 3 cells.
"""

from __future__ import annotations

import math

import pytest
from trainer_ply import write_trainer_ply

from fracture_gs.capture.scene import resolve
from fracture_gs.io.config import config_from_dict

DX = 0.0625


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path, _ = write_trainer_ply(tmp_path_factory.mktemp("duration"), n=300, floaters=0, far=0)
    return path


def resolved(ply, frames: int, frame_dt: float, load: str, speed: float):
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "frames": frames,
        "frame_dt": frame_dt,
        "fill_interior": False,
        "capture": {"cells_across": 8, "load": load, "load_speed": speed},
    }
    return resolve(config_from_dict(doc))


@pytest.mark.parametrize(
    "frames, frame_dt, speed, origin_cells, nodes",
    [
        # 0.4 s at 0.1 m/s: 4 cm of travel; room x [0.16, 0.84]: origin ⌊2.56⌋ − 3 = −1, ⌈(0.84 + Δx)/Δx⌉ + 4 = 19
        (20, 0.02, 0.1, -1, 19),
        # 0.4 s at 0.3 m/s: 12 cm; room x [0.08, 0.92]: origin ⌊1.28⌋ − 3 = −2, ⌈(0.92 + 2Δx)/Δx⌉ + 4 = 21
        (20, 0.02, 0.3, -2, 21),
        # 0.2 s at 0.3 m/s: 6 cm; room x [0.14, 0.86]: origin ⌊2.24⌋ − 3 = −1, ⌈(0.86 + Δx)/Δx⌉ + 4 = 19
        (10, 0.02, 0.3, -1, 19),
    ],
)
def test_a_pulls_grips_move_for_the_whole_run_and_the_room_holds_their_travel(
    ply, frames, frame_dt, speed, origin_cells, nodes
):
    """Both grips move at ±v from t = 0 to frames × frame_dt; the grid reaches 0.1·size + v·frames·frame_dt past
    the object's ends along x (plus the 3 wall cells), so a faster pull or a longer run gets a wider grid."""
    cap = resolved(ply, frames, frame_dt, "pull", speed)
    grips = cap.cfg.sim.boundaries
    assert [b.velocity for b in grips] == [(-speed, 0.0, 0.0), (speed, 0.0, 0.0)]
    assert [(b.start, b.end) for b in grips] == [(0.0, pytest.approx(frames * frame_dt, rel=1e-12))] * 2
    sim = cap.cfg.sim
    assert sim.dx == DX
    assert sim.grid_origin[0] == pytest.approx(origin_cells * DX, abs=1e-12)
    assert sim.grid_shape[0] == nodes


def test_a_crush_too_slow_to_reach_its_stop_says_how_far_it_gets_in_the_run(ply):
    """A plate pressing at 1 cm/s would need tens of seconds to reach its stop: over a 0.4 s run (20 frames of
    0.02 s) the note says it moves 0.004 m in this run."""
    cap = resolved(ply, 20, 0.02, "crush", 0.01)
    note = next(n for n in cap.notes if n.startswith("load crush"))
    assert "0.004 m in this run, it would stop" in note, note
    press = cap.cfg.sim.boundaries[1]
    assert press.velocity == (0.0, 0.0, -0.01) and press.end > 0.4 and math.isfinite(press.end)
