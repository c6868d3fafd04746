"""Pinned rule of a parsed sweep spec (`fracture_gs.sweep.spec`: SweepSpec, AccuracyBlock, SceneBlock): a spec is
a value fixed by its checks. Every field of the spec and of each block refuses assignment, so no caller can slip an
unchecked value (a list where a tuple of checked numbers was, a label with "|", a cells count of 0) between
load_spec and the expansion; and two loads of one file are equal and hash alike, so a spec can key a cache.

Unit-level calls only: specs are parsed, never expanded.
"""

from __future__ import annotations

import dataclasses

import pytest

from fracture_gs.sweep.spec import AccuracyBlock, SceneBlock, SweepSpec, load_spec

SPEC = (
    '[sweep]\ntitle = "T"\n'
    '[[accuracy]]\nlabel = "dx"\ncase = ["bar"]\ncells = [16, 32]\ncfl = 0.4\n'
    '[[scene]]\nconfig = "bread"\nvariant = ["baseline", "full"]\ncells = [32]\ndt = [1e-4]\nseed = [0, 1]\n'
    "frames = 2\n[scene.material]\nE = [1e5, 2e5]\n"
)


def _load(tmp_path) -> SweepSpec:
    path = tmp_path / "s.toml"
    path.write_text(SPEC)
    return load_spec(path)


def test_every_field_of_a_loaded_spec_refuses_assignment(tmp_path):
    """Assigning any field of the spec, of its accuracy block or of its scene block raises FrozenInstanceError and
    leaves the checked value in place."""
    spec = _load(tmp_path)
    (acc,) = spec.accuracy
    (scene,) = spec.scenes
    assert (type(acc), type(scene)) == (AccuracyBlock, SceneBlock)
    for obj in (spec, acc, scene):
        for f in dataclasses.fields(obj):
            before = getattr(obj, f.name)
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(obj, f.name, None)
            assert getattr(obj, f.name) == before
    assert (scene.cells, scene.steps, scene.seeds, scene.frames) == ((32,), (("dt", 1e-4),), (0, 1), 2)
    assert scene.overrides == (("material.E", (1e5, 2e5)),)


def test_two_loads_of_one_spec_are_equal_values_that_hash_alike(tmp_path):
    """The blocks hold tuples only, so each block and the whole spec hash; two loads give equal objects with
    equal hashes, and a block differing in one field (the label) is unequal."""
    one, two = _load(tmp_path), _load(tmp_path)
    assert one == two and one is not two
    assert hash(one) == hash(two)
    assert hash(one.scenes[0]) == hash(two.scenes[0]) and hash(one.accuracy[0]) == hash(two.accuracy[0])
    assert len({one.scenes[0], two.scenes[0], dataclasses.replace(one.scenes[0], label="other")}) == 2
