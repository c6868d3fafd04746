"""Shared by the bad-input rounds (tests/test_bad_input_round*.py): the one-sentence rule of an error message and
the smallest captured-scene config document."""

from __future__ import annotations


def one_line(err: BaseException) -> str:
    """The error's message, asserted to be one non-empty sentence (one line ending in a full stop)."""
    msg = str(err)
    assert msg.strip() and "\n" not in msg and msg.rstrip().endswith("."), msg
    return msg


def capture_doc(scene: str = "scene.ply", **capture) -> dict:
    """A config document of a captured scene `scene` with these [capture] keys."""
    return {"extends": "capture", "scene": scene, "capture": capture}
