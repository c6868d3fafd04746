"""Pinned messages of config building and validation (`fracture_gs.io.config.build` / `validate`): what a wrong
value is called (a TOML date, an array of one item or several), optional fields (null allowed from the dict API,
a wrong type named as for any field), an array-of-tables entry that is not a table (with a fix that is valid
TOML), numbers given as text, and the scene, material_property and latch-time checks.

Each call builds one config from a dict (milliseconds); nothing is simulated.
"""

from __future__ import annotations

import datetime

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict

BASE = {"variants": ["baseline"]}


def refused(**over) -> str:
    with pytest.raises(ConfigError) as info:
        config_from_dict({**BASE, **over})
    text = str(info.value)
    assert text.startswith("<dict>: ") and "\n" not in text
    return text[len("<dict>: ") :]


@pytest.mark.parametrize(
    "value, called",
    [
        (datetime.date(1979, 5, 27), "a date"),
        (datetime.time(7, 32), "a time"),
        ([1], "an array of 1 item"),
        ([1, 2], "an array of 2 items"),
        ({}, "a table"),
        (True, "the boolean true"),
        (2.0, "the number 2.0"),
    ],
)
def test_a_wrong_value_is_called_what_it_is(value, called):
    """An integer key given another kind of value names that kind (TOML dates and times by their type name, arrays
    with their length in the right number) and ends with the key's default as the example."""
    assert refused(frames=value) == f"frames must be an integer, not {called}; write it like frames = 30."


def test_a_number_given_as_text_is_told_to_drop_the_quotes():
    """A number written in quotes gets the fix to write it without them, for a plain and for an optional key; text
    that is no number gets the plain message."""
    assert refused(frames="12") == (
        "frames must be an integer, not the string '12'; write the number without quotes, e.g. frames = 12."
    )
    assert refused(topology={"latch_time": " 0.5"}) == (
        "topology.latch_time must be a number, not the string ' 0.5'; write the number without quotes, e.g. "
        "latch_time = 0.5."
    )
    assert refused(topology={"latch_time": "soon"}) == "topology.latch_time must be a number, not the string 'soon'."


def test_an_optional_key_takes_null_from_the_dict_api_and_converts_integers():
    """An optional key (topology.latch_time) may be None in a dict (TOML cannot say null; it means unset), and an
    integer for a float key is read as that float."""
    cfg = config_from_dict({**BASE, "topology": {"latch_time": None}, "material": {"E": 2000}})
    assert cfg.topology.latch_time is None
    assert cfg.material.E == 2000.0 and isinstance(cfg.material.E, float)
    assert config_from_dict({**BASE, "topology": {"latch_time": 1}}).topology.latch_time == 1.0


@pytest.mark.parametrize(
    "over, message",
    [
        (
            {"material_map": [3]},
            "material_map[0] must be a table, not the number 3; write it as a [[material_map]] table.",
        ),
        (
            {"topology": {"planes": ["x"]}},
            "topology.planes[0] must be a table, not the string 'x'; write it as a [[topology.planes]] table.",
        ),
        (
            {"capture": {"regions": [[1]]}},
            "capture.regions[0] must be a table, not an array of 1 item; write it as a [[capture.regions]] table.",
        ),
        ({"sim": 3}, "[sim] must be a table, not the number 3; write it as a [sim] section."),
        (
            {"render": {"camera": "front"}},
            "[render.camera] must be a table, not the string 'front'; write it as a [render.camera] section.",
        ),
        (
            {"sim": {"boundaries": [1]}},
            "sim.boundaries[0] must be a table, not the number 1; write it like [[sim.boundaries]] tables with type = "
            '"plane", "cuboid", "sphere" or "region".',
        ),
    ],
)
def test_a_table_given_as_something_else_gets_a_fix_in_toml(over, message):
    """A section or an entry of an array of tables given as a scalar or an array names where it is and a fix that
    is valid TOML: [section] for a section, [[array]] for an array entry (never `[material_map[0]]`)."""
    assert refused(**over) == message


def test_the_scene_must_be_built_in_or_a_splat_file():
    """scene names a built-in scene or a splat file; anything else is refused listing the built-ins and the splat
    suffixes."""
    text = refused(scene="castle")
    assert text.startswith("scene = 'castle' is neither a built-in scene nor a splat file; use one of bread, ")
    assert text.endswith("or a path to a .ply, .compressed.ply, .splat or .spz scene.")
    assert config_from_dict({**BASE, "scene": "castle.spz"}).scene == "castle.spz"


def test_material_property_may_be_unset_but_not_empty():
    """material_property names the PLY property with the material labels: unset is fine, an empty name is
    refused."""
    assert config_from_dict(BASE).material_property is None
    assert refused(material_property="") == (
        "material_property is empty; name the PLY property holding the labels or remove the key."
    )


def test_latch_times_may_be_zero_but_not_negative():
    """topology.latch_time and each oracle plane's latch_time are times in seconds: 0 (latch at once) is allowed,
    a negative time is refused naming the key."""
    plane = {"normal": [1.0, 0.0, 0.0], "point": [0.5, 0.5, 0.5]}
    ok = config_from_dict({**BASE, "topology": {"latch_time": 0.0, "planes": [{**plane, "latch_time": 0.0}]}})
    assert ok.topology.latch_time == 0.0 and ok.topology.planes[0].latch_time == 0.0
    assert refused(topology={"latch_time": -0.5}) == (
        "topology.latch_time = -0.5 must be at least 0.0; use a time in seconds >= 0."
    )
    assert refused(topology={"planes": [{**plane, "latch_time": -1.0}]}) == (
        "topology.planes[0].latch_time = -1.0 must be at least 0.0; use a time in seconds >= 0."
    )
