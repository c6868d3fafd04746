"""Pinned rule of a [scene.set] dotted key that points nowhere (`fracture_gs.sweep.expansion.scene_config` with
`_set_dotted`): the cell is refused with one sentence that starts with the spec file, names the override and the
first part of its path the config lacks (an index past the end of an array, a non-number index, a path walking
into a plain value), and ends with the fix; the error's field is `<table>.set.<key>`. A missing table on the way
is not this error: it is created, and the config's own check then names the unknown key.

Unit-level calls only: specs are parsed and expanded (configs validated, nothing simulated).
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep.expansion import expand
from fracture_gs.sweep.spec import load_spec

FIX = "check the dotted path (array entries by index, e.g. material_map.0.E)."


def expanded(tmp_path, key: str):
    path = tmp_path / "s.toml"
    path.write_text(f'[[scene]]\nconfig = "bread"\nvariant = "baseline"\n[scene.set]\n"{key}" = [1.0]\n')
    spec = load_spec(path)
    with pytest.raises(ConfigError) as info:
        expand(spec)
    return spec, info.value


@pytest.mark.parametrize(
    "key, entry",
    [
        ("material_map.5.E", "material_map.5"),  # bread's map has two entries: index 5 is past its end
        ("material_map.2.E", "material_map.2"),  # the first index past the end
        ("material_map.x.E", "material_map.x"),  # an array is indexed by number only
        ("material_map.2", "material_map.2"),  # the index as the path's last part
        ("material_map.E", "material_map.E"),  # a name as the last part of an array path
        ("frames.x", "frames"),  # frames is a number, not a table
    ],
)
def test_a_dotted_key_that_points_nowhere_names_the_first_missing_entry(tmp_path, key, entry):
    """The sentence names the spec, the override as written, the first missing part of its path and the fix; the
    error's field is scene[0].set.<key>."""
    spec, error = expanded(tmp_path, key)
    assert str(error) == (f"{spec.source}: scene[0] override {key!r}: the config has no entry {entry!r}; {FIX}")
    assert (error.source, error.field) == (spec.source, f"scene[0].set.{key}")


def test_the_last_array_entry_is_reachable_and_one_past_it_is_not(tmp_path):
    """bread's material_map has two entries: material_map.1.E is set in the cell, material_map.2.E is refused
    (an off-by-one in the bound would accept it or refuse the last entry)."""
    path = tmp_path / "s.toml"
    path.write_text('[[scene]]\nconfig = "bread"\nvariant = "baseline"\n[scene.set]\n"material_map.1.E" = [3e3]\n')
    (cell,) = expand(load_spec(path))
    assert [m["E"] for m in cell.config["material_map"]][1] == 3e3 and len(cell.config["material_map"]) == 2
    _, error = expanded(tmp_path, "material_map.2.E")
    assert "has no entry 'material_map.2'" in str(error)


def test_a_missing_table_on_the_way_is_made_and_judged_by_the_config(tmp_path):
    """ "topology.extra.x" creates the missing table, so it is the config's check that refuses it (an unknown key
    in [topology]), not the missing-entry sentence."""
    spec, error = expanded(tmp_path, "topology.extra.x")
    assert str(error).startswith(f"{spec.source}: scene[0] (bread, baseline, topology.extra.x = 1) gives an ")
    assert "has no entry" not in str(error)
