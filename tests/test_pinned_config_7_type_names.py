"""How a config annotation reads in "must be ..." messages (`io/config/build._type_name`): each kind of annotation
the config dataclasses use, and the two that have no key of their own today (a nested table, a list), read as a
user writes them in TOML: a table is "a table", anything else an array; Optional reads as its inner type; tuples
count their items and pluralize them. Through `config_from_dict` the tuple and scalar forms reach the user."""

from __future__ import annotations

from typing import Literal, Optional

import pytest

from fracture_gs.config import CameraConfig, ContactConfig, MaterialConfig
from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.config.build import _type_name


@pytest.mark.parametrize(
    "tp, text",
    [
        (float, "a number"),
        (int, "an integer"),
        (bool, "true or false"),
        (str, "a string"),
        (Optional[float], "a number"),
        (Optional[int], "an integer"),
        (Literal["a", "b"], "one of 'a', 'b'"),
        (tuple[float, float, float], "an array of 3 numbers"),
        (tuple[int, int, int], "an array of 3 integers"),
        (tuple[tuple[float, float, float], tuple[float, float, float]], "an array of 2 arrays of 3 numbers"),
        (CameraConfig, "a table"),
        (ContactConfig, "a table"),
        (Optional[MaterialConfig], "a table"),
        (list, "an array"),
        (list[str], "an array"),
    ],
)
def test_each_annotation_reads_as_the_toml_a_user_writes(tp, text):
    """A dataclass annotation (a [section]) reads "a table", a list "an array"; scalars, Literal choices, Optional
    and nested tuples each read their own way."""
    assert _type_name(tp) == text


@pytest.mark.parametrize(
    "sim, message",
    [
        ({"gravity": 3}, "sim.gravity must be an array of 3 numbers, not the number 3"),
        ({"grid_shape": [1, 2]}, "sim.grid_shape must be an array of 3 integers, not an array of 2 items"),
        ({"adaptive_dt": 1}, "sim.adaptive_dt must be true or false, not the number 1"),
        ({"grid_bounds": 0}, "sim.grid_bounds must be an array of 2 arrays of 3 numbers, not the number 0"),
    ],
)
def test_the_reading_reaches_the_users_message(sim, message):
    """A wrong type in a scene's [sim] is refused with the annotation's reading: "must be <reading>, not <value>"."""
    with pytest.raises(ConfigError) as info:
        config_from_dict({"variants": ["baseline"], "sim": sim})
    assert message in str(info.value)
