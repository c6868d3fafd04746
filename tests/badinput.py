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


def refused(doc: dict, key: str) -> str:
    """The one-sentence ConfigError that loading `doc` raises, which must name `key`."""
    import pytest

    from fracture_gs.errors import ConfigError
    from fracture_gs.io.config import config_from_dict

    with pytest.raises(ConfigError) as info:
        config_from_dict(doc, "probe.toml")
    msg = one_line(info.value)
    assert key in msg, msg
    return msg
