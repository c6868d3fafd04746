"""Pinned rules of what a captured scene says about its load and where its automatic camera looks
(`capture.scene.resolve` and `capture.scene._camera`), round seventeen:

- load note: `capture.load = "auto"` appends the choice and its reason to the plan's note
  ("(capture.load = 'auto' chose drop: <why>; --load sets it)"); a load named by the user gets no such clause.
  A load with boundaries replaces the config's own initial_velocity and sim.gravity; those the config set (non-zero
  and different from the load's) are named after the note, "is not used" for one and "are not used" for two;
  `capture.load = "none"` replaces nothing and says nothing of them.
- auto camera: frames a box that spans, along x, from midway between the object's and the room's lower x to
  midway between their upper x (the opening of a pull shows), along y the object's own extent, and along z from
  the lower of the object's bottom and 5 % of the size above the room's floor up to the object's top.

A 400-Gaussian trainer-like PLY; the resolution step is replaced by a fixed 8 cells and nothing is filled, so each
resolve takes a fraction of a second.
"""

from __future__ import annotations

import pytest
import torch
from captureutil import fixed_resolution  # noqa: F401 - autouse: every capture here has 8 cells across
from trainer_ply import write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.capture.camera import frame_box
from fracture_gs.io.config import config_from_dict

DROP = "load drop: falls from 0.1 m at 1 m/s onto a friction floor (up to 8 cracks)"
PULL = "load pull: grips on the outer 15 % of each end along x, 0.1 m/s apart each, no gravity"
CHOSE = (
    " (capture.load = 'auto' chose drop: a fall breaks any shape without grips (0.6× as tall as wide); --load sets it)"
)
KEEPS = ' not used (the load sets them: capture.load = "none" keeps the config\'s own)'
VELOCITY = "initial_velocity [1.0, 0.0, 0.0]"
GRAVITY = "sim.gravity [0.0, 0.0, -5.0]"


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path, _ = write_trainer_ply(tmp_path_factory.mktemp("notes17"), n=400, floaters=0, far=0)
    return path


def config(ply, load, **top):
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        **top,
        "capture": {"load": load, "ground": "none", "outlier_neighbours": 0, "up": "-y"},
    }
    return config_from_dict(doc)


def load_note(ply, load, **top) -> str:
    (note,) = [n for n in scene.resolve(config(ply, load, **top), "cpu").notes if n.startswith("load")]
    return note


def test_only_an_automatic_load_states_its_choice_and_reason(ply):
    """load = "auto" (no ground: a drop) appends its choice and why; load = "drop" and "pull", named by the user,
    print the plan's note alone."""
    assert load_note(ply, "auto") == DROP + CHOSE
    assert load_note(ply, "drop") == DROP
    assert load_note(ply, "pull") == PULL


@pytest.mark.parametrize(
    "load, head", [("auto", DROP + CHOSE), ("drop", DROP), ("pull", PULL)], ids=["auto", "drop", "pull"]
)
def test_one_replaced_value_is_not_used_and_two_are_not_used(ply, load, head):
    """A config initial_velocity (1, 0, 0) that the load replaces is named with "is"; with sim.gravity
    (0, 0, −5) as well both are named, joined by "and", with "are"."""
    one = load_note(ply, load, initial_velocity=[1.0, 0.0, 0.0])
    assert one == f"{head}; the config's {VELOCITY} is{KEEPS}"
    two = load_note(ply, load, initial_velocity=[1.0, 0.0, 0.0], sim={"gravity": [0.0, 0.0, -5.0]})
    assert two == f"{head}; the config's {VELOCITY} and {GRAVITY} are{KEEPS}"


def test_no_load_replaces_nothing(ply):
    """load = "none" has no boundaries: the config's initial velocity and gravity stay and are not named."""
    note = load_note(ply, "none", initial_velocity=[1.0, 0.0, 0.0], sim={"gravity": [0.0, 0.0, -5.0]})
    assert note == "load none: only the boundaries of the config"


def t(*v) -> torch.Tensor:
    return torch.tensor(v, dtype=torch.float64)


@pytest.mark.parametrize(
    "room_lo, frame_lo",
    [
        # room floor 0, far below the object's bottom 3: the frame reaches down to 5 % of the size above it
        ((-1.0, 0.0, 0.0), (0.0, 2.0, 0.025)),
        # room floor 2.99: 5 % of the 0.5 m size above it is 3.015, above the object's bottom 3: bottom 3 kept
        ((-3.0, 0.0, 2.99), (-1.0, 2.0, 3.0)),
        # room floor 2.9: 2.925 is below the object's bottom: the frame reaches down to it
        ((5.0, 0.0, 2.9), (3.0, 2.0, 2.925)),
    ],
)
def test_the_auto_camera_frames_midway_to_the_room_along_x(ply, room_lo, frame_lo):
    """Object [1, 2] × [2, 3] × [3, 4], room upper corner (6, 5, 8), size 0.5 m: the framed box runs along x from
    ½(1 + room_lo_x) to ½(2 + 6) = 4, along y over the object's [2, 3], along z from min(3, room_lo_z + 0.025)
    to 4; the camera is frame_box of that box at the panel's size, its orbit kept, and the note says so."""
    cfg = config(ply, "none")
    cfg.capture.camera, cfg.capture.size = "auto", 0.5
    cfg.render.width, cfg.render.height = 320, 240
    cfg.render.camera.orbit_degrees = 30.0
    notes = []
    scene._camera(cfg, [], None, t(1.0, 2.0, 3.0), t(2.0, 3.0, 4.0), t(*room_lo), t(6.0, 5.0, 8.0), notes)
    want = frame_box(frame_lo, (4.0, 3.0, 4.0), 320, 240)
    got = cfg.render.camera
    assert got.eye == pytest.approx(want.eye, abs=1e-12) and got.target == pytest.approx(want.target, abs=1e-12)
    assert (got.up, got.fov_deg, got.orbit_degrees) == (want.up, want.fov_deg, 30.0)
    assert notes == ["camera: frames the object from the front, 20° above"]
    assert cfg.capture.camera == "config"
