"""Pinned rule of the room each capture load needs (`capture.loads.plan_load` → `capture.scene._room`), round
nine: only what moves widens the room along x — a grip's or a ball's velocity, a kick's Δv — by |v|·duration (at
most half the size); a floor plane does not move, so it adds no travel, only the 0.05·size under it and the
0.2·size in x and y for the pieces.

Hand-computed for an object at (0.25, 0.38, 0.35)–(0.75, 0.62, 0.65), size 0.5 m (margin 0.05 m), Δx = 2 cm.
Unit-level calls.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import LoadPlan, plan_load
from fracture_gs.capture.scene import _room
from fracture_gs.config import PlaneBoundary

LO, HI = torch.tensor([0.25, 0.38, 0.35], dtype=torch.float64), torch.tensor([0.75, 0.62, 0.65], dtype=torch.float64)
DX, SIZE = 0.02, 0.5


def room(kind: str, duration: float):
    plan = plan_load(kind, LO, HI, DX, SIZE, 0.0, duration)
    lo, hi = _room(SIZE, LO.clone(), HI.clone(), plan, duration)
    return lo.tolist(), hi.tolist()


def test_a_drop_floor_adds_no_travel():
    """drop: a still floor plane only (the fall is an initial velocity, not a boundary): x and y get the margin and
    0.2·size for the pieces (0.25 − 0.05 − 0.1 = 0.1 to 0.9; 0.23 to 0.77), z reaches 0.05·size under the floor
    at 0.25 (0.225) — over a 0.3 s run, with nothing moving along x, no more."""
    lo, hi = room("drop", 0.3)
    assert lo == pytest.approx([0.1, 0.23, 0.225], abs=1e-12) and hi == pytest.approx([0.9, 0.77, 0.7], abs=1e-12)


def test_a_floor_alone_adds_no_travel_whatever_the_run_length():
    """A lone floor plane (no velocity) gives the same room over 0.01 s and over 10 s."""
    floor = PlaneBoundary(point=(0.0, 0.0, 0.25), normal=(0.0, 0.0, 1.0), mode="friction", friction=0.4)
    plan = LoadPlan(boundaries=[floor], floor=0.25)
    short = _room(SIZE, LO.clone(), HI.clone(), plan, 0.01)
    long = _room(SIZE, LO.clone(), HI.clone(), plan, 10.0)
    assert short[0].tolist() == pytest.approx(long[0].tolist(), abs=1e-12)
    assert short[0][0] == pytest.approx(0.1, abs=1e-12) and long[1][0] == pytest.approx(0.9, abs=1e-12)


def test_an_impact_widens_by_its_kick_beside_a_still_floor():
    """impact: the 4 m/s kick over a 0.01 s run travels 4 cm on both x sides (the floor beside it adds nothing):
    x 0.25 − 0.05 − 0.04 − 0.1 = 0.06 to 0.94; the floor at 0.32 puts z at min(0.3, 0.32 − 0.025) = 0.295."""
    lo, hi = room("impact", 0.01)
    assert lo == pytest.approx([0.06, 0.23, 0.295], abs=1e-12) and hi == pytest.approx([0.94, 0.77, 0.7], abs=1e-12)


def test_pull_grips_widen_by_their_opening_without_a_floor():
    """pull: grips at 0.1 m/s for 0.3 s travel 3 cm along x; no floor, so y and z keep the margin only."""
    lo, hi = room("pull", 0.3)
    assert lo == pytest.approx([0.17, 0.33, 0.3], abs=1e-12) and hi == pytest.approx([0.83, 0.67, 0.7], abs=1e-12)
