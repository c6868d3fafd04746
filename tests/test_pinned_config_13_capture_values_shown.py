"""Pinned rule of how a `[capture]` value is written in the refusal "capture.<key> = <value> has no effect" on a
built-in scene (`io.config.combinations`), round thirteen: as the user would write it back in TOML terms: a string
quoted, a boolean lower-case, a float in its shortest %g form, an integer as is, a list of numbers as a list, and a
list of lists by its length ("[3 entries]") so a 3×3 matrix does not flood the sentence.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict

TAIL = " has no effect: scene = 'bread' is a built-in scene, and [capture] prepares captured scenes"


@pytest.mark.parametrize(
    "key, value, shown",
    [
        ("camera", "trainer", "'trainer'"),
        ("fit", False, "false"),
        ("size", 0.25, "0.25"),
        ("max_particles", 5000, "5000"),
        ("outlier_std", 2, "2"),
        ("offset", [0.5, 0, 0.25], "[0.5, 0.0, 0.25]"),
        ("rotation", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "[3 entries]"),
    ],
)
def test_a_capture_key_on_a_built_in_scene_is_shown_as_written(key, value, shown):
    """`capture.<key> = <shown>` starts the refusal, the value written as TOML would read it."""
    with pytest.raises(ConfigError) as info:
        config_from_dict({"extends": "bread", "capture": {key: value}})
    assert str(info.value).startswith(f"<dict>: capture.{key} = {shown}{TAIL}"), str(info.value)
