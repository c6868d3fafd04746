"""Pinned rule of when a captured scene reads the trainer's cameras.json (`capture.scene.resolve`), round ten:
the views are read only when something uses them, i.e. when the up axis is found from them (capture.up = "auto"
and no capture.rotation) or when the camera is a trainer view (capture.camera = "trainer"). Otherwise the file
is not opened at all, so a broken cameras.json beside the PLY is no error: the message for a broken file tells
the user exactly that ("set capture.up and capture.camera = "auto"").

A 400-Gaussian trainer-like PLY (y down in the scene) in a model folder; the resolution step is replaced by a
fixed 8 cells (its own rules are pinned elsewhere) and nothing is filled, so each resolve takes a fraction of a
second.
"""

from __future__ import annotations

import pytest
from captureutil import fixed_resolution  # noqa: F401 - autouse: every capture here has 8 cells across
from trainer_ply import write_cameras, write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.errors import SceneError
from fracture_gs.io.config import config_from_dict

EYE = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def model(folder, cameras: str):
    """A trainer model folder whose cameras.json is 'good' (8 upright views), 'broken' (not JSON) or 'none'."""
    ply, _ = write_trainer_ply(folder, n=400, floaters=0, far=0)
    if cameras == "good":
        write_cameras(folder / "cameras.json")
    elif cameras == "broken":
        (folder / "cameras.json").write_text("this is not a cameras.json")
    return ply


def resolve(ply, **capture):
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        "capture": {"load": "none", "ground": "none", "outlier_neighbours": 0, **capture},
    }
    return scene.resolve(config_from_dict(doc), "cpu")


def fit_note(notes) -> str:
    return next(n for n in notes if "m per scene unit" in n)


def test_an_automatic_up_axis_comes_from_the_trainer_cameras_even_with_an_automatic_camera(tmp_path):
    """capture.up = "auto", capture.camera = "auto": the 8 views (their y axes point down the scene's +y) are read
    and give the up axis (−y), not the COLMAP convention assumed without views; and the assumed one is what a
    model folder without cameras.json gets."""
    with_views = resolve(model(tmp_path / "a", "good"), up="auto", camera="auto")
    assert fit_note(with_views.notes).startswith("up axis from the 8 trainer cameras (closest to -y); scale ")
    without = resolve(model(tmp_path / "b", "none"), up="auto", camera="auto")
    assert fit_note(without.notes).startswith("up axis -y assumed (COLMAP's convention; set capture.up); scale ")


@pytest.mark.parametrize("up, rotation", [("-y", None), ("+z", None), ("auto", EYE), ("+z", EYE)])
def test_a_given_up_axis_or_rotation_with_an_automatic_camera_never_opens_cameras_json(tmp_path, up, rotation):
    """A broken cameras.json beside the PLY is not read when neither the up axis (given by capture.up or implied
    by capture.rotation) nor the camera (capture.camera = "auto") needs it: the scene resolves, and the fit note
    names the source of the up axis that was used."""
    capture = {"up": up, "camera": "auto"} | ({} if rotation is None else {"rotation": rotation})
    out = resolve(model(tmp_path, "broken"), **capture)
    note = fit_note(out.notes)
    if rotation is None:
        assert note.startswith(f"up axis {up} (capture.up); scale ")
    else:
        given = "fit: capture.rotation from the config, scale and offset automatic (up axis from capture.rotation); "
        assert note.startswith(given)
    assert out.cfg.capture.camera == "config"
    assert out.notes[-1] == "camera: frames the object from the front, 20° above"


@pytest.mark.parametrize("up", ["auto", "-y"])
def test_the_camera_or_the_up_axis_needing_the_views_reads_a_broken_file_and_says_so(tmp_path, up):
    """When the views are needed (an automatic up axis, or a trainer camera whatever the up axis), a broken
    cameras.json is a SceneError naming the file and the way out."""
    ply = model(tmp_path, "broken")
    for capture in ({"up": up, "camera": "trainer"},) + (({"up": "auto", "camera": "auto"},) if up == "auto" else ()):
        with pytest.raises(SceneError, match=r"cameras\.json: not a trainer cameras\.json .*set capture\.up and"):
            resolve(ply, **capture)


def test_a_trainer_camera_with_a_given_up_axis_reads_the_views(tmp_path):
    """capture.camera = "trainer" with capture.up = "-y": the views are read for the camera (view 0, named
    00000), while the up axis is the given one."""
    out = resolve(model(tmp_path, "good"), up="-y", camera="trainer", view=0)
    assert fit_note(out.notes).startswith("up axis -y (capture.up); scale ")
    assert out.notes[-1] == "camera: trainer view 0 (00000)"
