"""Which [scene.set] keys a [[scene]] table's own keys own (`fracture_gs.sweep.spec._refuse_shadowed`): a config
key that a table key sets is refused in [scene.set] when that table key is given (one of the two would do
nothing), and accepted, as an axis of its own, when it is not: frames, particles, sim.dt (owned by dt), sim.cfl
(cfl), sim.adaptive_dt (dt or cfl), sim.dx, sim.grid_shape and capture.cells_across (cells). variants, preset
and topology.seed are set by every cell (the variant and seed axes, the preset's rescaling), so [scene.set] may
never hold them. The refusal names the key, the owner and the fix in one sentence.

Unit-level calls only: specs are parsed, never expanded. The owner table is written out here by hand.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep.spec import load_spec

SCENE = '[[scene]]\nconfig = "bread"\n'
OPTIONAL = [
    # (the [scene.set] key, its TOML value, the owning table key, the owner's TOML line)
    ("frames", "[5]", "frames", "frames = 2"),
    ("particles", "[500]", "particles", "particles = 300"),
    ("sim.dt", "[2e-4]", "dt", "dt = [1e-4]"),
    ("sim.cfl", "[0.2]", "cfl", "cfl = [0.3]"),
    ("sim.adaptive_dt", "[true]", "dt", "dt = [1e-4]"),
    ("sim.dx", "[0.01]", "cells", "cells = [16]"),
    ("sim.grid_shape", "[[16, 16, 16]]", "cells", "cells = [16]"),
    ("capture.cells_across", "[40]", "cells", "cells = [16]"),
]
ALWAYS = [
    ("variants", '[["full"]]', "variant"),
    ("preset", '["paper"]', "preset"),
    ("topology.seed", "[5]", "seed"),
]


def spec(tmp_path, table_lines: str, key: str, value: str):
    path = tmp_path / "s.toml"
    path.write_text(f'{SCENE}{table_lines}[scene.set]\n"{key}" = {value}\n')
    return path


def refused(path) -> str:
    with pytest.raises(ConfigError) as info:
        load_spec(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message[len(f"{path}: ") :]


def shadow(key: str, owner: str) -> str:
    return (
        f"scene[0].set.{key} sets what scene[0].{owner} sets for every cell, so one of them would do nothing; "
        f"give the values as scene[0].{owner} = [...] and remove {key} from [scene.set]."
    )


@pytest.mark.parametrize("key, value, owner, line", OPTIONAL, ids=[k for k, *_ in OPTIONAL])
def test_a_set_key_whose_owner_is_absent_is_an_axis_of_its_own(tmp_path, key, value, owner, line):
    """Without its owning table key, the [scene.set] key is kept as an override with its values (nothing else
    sets it, so it is no shadow)."""
    (s,) = load_spec(spec(tmp_path, "", key, value)).scenes
    assert len(s.overrides) == 1 and s.overrides[0][0] == key and len(s.overrides[0][1]) == 1


@pytest.mark.parametrize("key, value, owner, line", OPTIONAL, ids=[k for k, *_ in OPTIONAL])
def test_a_set_key_beside_its_owner_is_refused_naming_both(tmp_path, key, value, owner, line):
    """With its owning table key also given, the [scene.set] key is refused naming itself, the owner and the
    fix."""
    assert refused(spec(tmp_path, line + "\n", key, value)) == shadow(key, owner)


def test_the_adaptive_step_is_owned_by_a_cfl_axis_too(tmp_path):
    """sim.adaptive_dt is set by a cfl axis as well as by a dt axis (a CFL step is adaptive): beside cfl alone
    it is refused naming cfl (the key the user gave), beside dt naming dt; beside another owner's key (cells) it
    is not."""
    assert refused(spec(tmp_path, "cfl = [0.3]\n", "sim.adaptive_dt", "[true]")) == shadow("sim.adaptive_dt", "cfl")
    assert refused(spec(tmp_path, "dt = [1e-4]\ncfl = [0.3]\n", "sim.adaptive_dt", "[true]")) == shadow(
        "sim.adaptive_dt", "dt"
    )
    (s,) = load_spec(spec(tmp_path, "cells = [16]\n", "sim.adaptive_dt", "[true]")).scenes
    assert s.overrides == (("sim.adaptive_dt", (True,)),) and s.cells == (16,)


def test_cfl_owns_only_the_cfl_number(tmp_path):
    """sim.cfl in [scene.set] is refused beside cfl only: beside dt, cells or frames it stays an axis (and so
    does sim.dt beside cfl)."""
    for line in ("dt = [1e-4]", "cells = [16]", "frames = 3"):
        (s,) = load_spec(spec(tmp_path, line + "\n", "sim.cfl", "[0.2, 0.4]")).scenes
        assert s.overrides == (("sim.cfl", (0.2, 0.4)),)
    (s,) = load_spec(spec(tmp_path, "cfl = [0.3]\n", "sim.dt", "[2e-4]")).scenes
    assert s.overrides == (("sim.dt", (2e-4,)),) and s.steps == (("cfl", 0.3),)


@pytest.mark.parametrize("key, value, owner", ALWAYS, ids=[k for k, *_ in ALWAYS])
def test_a_key_every_cell_sets_is_never_a_set_key(tmp_path, key, value, owner):
    """variants, preset and topology.seed are set by every cell even when the table does not name its key
    (the config's own variants, the default seed 0), so [scene.set] refuses them alone."""
    assert refused(spec(tmp_path, "", key, value)) == shadow(key, owner)
