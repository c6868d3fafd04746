"""Pinned rules of what a captured scene says about the [render] settings its automatic choices replace
(`capture.scene.resolve`), round ten:

- panel: capture.panel = "auto" sets width × height to the device's size (640 × 480 on the CPU); a config whose
  [render] size is one of the automatic sizes (640 × 480, 1280 × 720) or the unset default (RenderConfig's)
  asked for nothing, so nothing is said; any other size, even one pixel off, was asked for, and the note names it
  and how to keep it (capture.panel = "config").
- camera: an automatic camera (capture.camera = "auto" or "trainer") replaces [render.camera] eye, target, up
  and fov_deg; those the config set to other than their defaults are named at the end of the camera note, with
  "is" for one and "are" for several; orbit_degrees is kept and not named. capture.camera = "config" uses them as
  written and its note says only that.

A 400-Gaussian trainer-like PLY; the resolution step is replaced by a fixed 8 cells (pinned elsewhere) and nothing
is filled, so each resolve takes a fraction of a second.
"""

from __future__ import annotations

import pytest
from captureutil import fixed_resolution  # noqa: F401 - autouse: every capture here has 8 cells across
from trainer_ply import write_cameras, write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.config import RenderConfig
from fracture_gs.io.config import config_from_dict

AUTO_CAMERA = "camera: frames the object from the front, 20° above"
KEEPS = ' (capture.camera = "config" keeps them)'


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    folder = tmp_path_factory.mktemp("overrides")
    path, _ = write_trainer_ply(folder, n=400, floaters=0, far=0)
    write_cameras(folder / "cameras.json")
    return path


def resolve(ply, render=None, **capture):
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        "capture": {"load": "none", "ground": "none", "outlier_neighbours": 0, "up": "-y", **capture},
    }
    if render is not None:
        doc["render"] = render
    return scene.resolve(config_from_dict(doc), "cpu")


def panel_notes(notes) -> list:
    return [n for n in notes if n.startswith("panel:")]


@pytest.mark.parametrize("size", [(640, 480), (1280, 720), (RenderConfig().width, RenderConfig().height)])
def test_an_automatic_panel_over_an_automatic_or_default_size_says_nothing(ply, size):
    """[render] 640 × 480, 1280 × 720 (the GPU's automatic size) or the unset default: on the CPU the panel is
    640 × 480 and no panel note is written (the config asked for no size of its own)."""
    out = resolve(ply, {"width": size[0], "height": size[1]})
    assert (out.cfg.render.width, out.cfg.render.height) == (640, 480)
    assert panel_notes(out.notes) == []


@pytest.mark.parametrize("size", [(1281, 720), (1280, 719), (1280, 722), (640, 482), (482, 640), (720, 1280)])
def test_an_automatic_panel_over_any_other_size_names_the_size_it_replaces(ply, size):
    """A [render] size that is not an automatic one, even one pixel (or one even step) off, or the right numbers
    swapped, is named in one note: the panel chosen, the size not used and the key that keeps it."""
    out = resolve(ply, {"width": size[0], "height": size[1]})
    assert (out.cfg.render.width, out.cfg.render.height) == (640, 480)
    assert panel_notes(out.notes) == [
        f'panel: 640×480 (capture.panel = "auto"); the [render] width × height the config gives, {size[0]}×{size[1]}, '
        'is not used (capture.panel = "config" keeps it)'
    ]


def test_a_config_panel_keeps_any_size_without_a_note(ply):
    """capture.panel = "config": 1281 × 720 is kept as written and nothing is said."""
    out = resolve(ply, {"width": 1281, "height": 720}, panel="config")
    assert (out.cfg.render.width, out.cfg.render.height) == (1281, 720)
    assert panel_notes(out.notes) == []


@pytest.mark.parametrize(
    "camera, named",
    [
        ({}, ""),
        ({"orbit_degrees": 90.0}, ""),  # kept by the automatic camera, so not named
        ({"eye": [1.0, -2.0, 0.5]}, "eye is"),
        ({"fov_deg": 55.0}, "fov_deg is"),
        ({"eye": [1.0, -2.0, 0.5], "fov_deg": 55.0}, "eye, fov_deg are"),
        ({"target": [0.1, 0.2, 0.3], "up": [0.0, 1.0, 0.0]}, "target, up are"),
        ({"eye": [1.0, -2.0, 0.5], "target": [0.1, 0.2, 0.3], "up": [0.0, 1.0, 0.0], "fov_deg": 55.0},
         "eye, target, up, fov_deg are"),
    ],
)  # fmt: skip
@pytest.mark.parametrize("kind", ["auto", "trainer"])
def test_an_automatic_camera_names_the_config_camera_keys_it_replaces(ply, camera, named, kind):
    """The camera note (the last note) of an automatic or trainer camera ends with the [render.camera] keys the
    config set and that are not used, "is" for one key and "are" for several; none set (or only orbit_degrees,
    which survives): the note is the camera's own."""
    out = resolve(ply, {"camera": camera}, camera=kind, view=0)
    own = AUTO_CAMERA if kind == "auto" else "camera: trainer view 0 (00000)"
    suffix = f"; the config's [render.camera] {named} not used{KEEPS}" if named else ""
    assert out.notes[-1] == own + suffix
    assert out.cfg.render.camera.orbit_degrees == camera.get("orbit_degrees", 0.0)
    assert out.cfg.capture.camera == "config"


@pytest.mark.parametrize(
    "camera",
    [{"eye": [1.0, -2.0, 0.5]}, {"eye": [1.0, -2.0, 0.5], "target": [0.1, 0.2, 0.3], "fov_deg": 55.0}],
)
def test_a_config_camera_is_used_as_written_and_its_note_says_only_that(ply, camera):
    """capture.camera = "config": the [render.camera] keys the config sets are the camera's, so the note is exactly
    "camera: [render.camera] as written" (nothing about keys not used), and it is the last note."""
    out = resolve(ply, {"camera": camera}, camera="config")
    assert out.notes[-1] == "camera: [render.camera] as written"
    assert not any("not used (capture.camera" in n for n in out.notes)
    for key, value in camera.items():
        got = getattr(out.cfg.render.camera, key)
        assert (list(got) if isinstance(got, tuple) else got) == value
