"""Pinned rule of a [[scene]] table's material axes (`fracture_gs.sweep.spec._refuse_shadowed`, `_scene_block`):
[scene.set] "material.X" is refused only when [scene.material] sets the same X (one of the two axes would do
nothing); another material field, an entry of material_map, or a key of another table that merely ends in the
same field name ("topology.E") is a different config entry and is not called a duplicate. Such a key is kept as
an axis of its own and the config's own check judges it when the cells are made.

Unit-level calls only: specs are parsed and, for the last rule, expanded (configs validated, nothing simulated).
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep.expansion import expand
from fracture_gs.sweep.spec import load_spec

SCENE = '[[scene]]\nconfig = "bread"\nvariant = "baseline"\n[scene.material]\nE = [1e5, 2e5]\n'


def spec_with_set(tmp_path, key: str, value: str):
    path = tmp_path / "s.toml"
    path.write_text(f'{SCENE}[scene.set]\n"{key}" = {value}\n')
    return path


def test_the_same_material_field_in_both_tables_is_refused(tmp_path):
    """[scene.material] E and [scene.set] "material.E" set one entry twice: ConfigError naming the set key, the
    material key and the fix, in one sentence."""
    path = spec_with_set(tmp_path, "material.E", "[3e5]")
    with pytest.raises(ConfigError) as info:
        load_spec(path)
    assert str(info.value) == (
        f"{path}: scene[0].set.material.E sets material.E, which scene[0].material.E sets too, so one of them would "
        "do nothing; give it once."
    )


@pytest.mark.parametrize(
    "key, value",
    [
        ("material.nu", "[0.25, 0.3]"),  # another field of the same table
        ("material_map.0.E", "[4000.0]"),  # an entry of the map, not of [material]
        ("topology.E", "[7.0]"),  # another table's key that ends in a material field's name
    ],
)
def test_a_different_entry_is_its_own_axis(tmp_path, key, value):
    """A [scene.set] key that is not material.E is no duplicate of [scene.material] E, however it ends: the spec
    loads and keeps both axes, E first (material before set), each with its values."""
    spec = load_spec(spec_with_set(tmp_path, key, value))
    (block,) = spec.scenes
    values = tuple(float(v) for v in value.strip("[]").split(","))
    assert block.overrides == (("material.E", (1e5, 2e5)), (key, values))


def test_a_key_of_another_table_is_judged_by_the_config_not_called_a_duplicate(tmp_path):
    """ "topology.E" (topology has no E) is refused when the cells are made, naming that key as the config's
    unknown entry, not as a second setter of material.E."""
    spec = load_spec(spec_with_set(tmp_path, "topology.E", "[7.0]"))
    with pytest.raises(ConfigError) as info:
        expand(spec)
    assert str(info.value).startswith(
        f"{spec.source}: scene[0] (bread, baseline, material.E = 100000, topology.E = 7) gives an invalid scene "
        "config: unknown key 'topology.E'; valid keys in [topology] are "
    )
