"""Pinned rules of reading a sweep spec (`fracture_gs.sweep.spec.load_spec`): every value's bounds on both sides,
the defaults of an almost empty spec, and the one-sentence message of each kind of malformed table or value
(the file, the key, the value and the fix), including those no other test reaches.

Unit-level calls only: specs are parsed, never expanded.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep.spec import DEFAULT_MAX_CELLS, SPEC_DIR, load_spec

ACC = '[[accuracy]]\ncase = ["spin"]\ncells = [16]\ncfl = 0.4\n'
SCENE = '[[scene]]\nconfig = "bread"\n'


def load(tmp_path, text: str, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return load_spec(path)


def refused(tmp_path, text: str) -> str:
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_spec(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message[len(f"{path}: ") :]


def acc(cells="[16]", cfl="0.4", case='["spin"]') -> str:
    return f"[[accuracy]]\ncase = {case}\ncells = {cells}\ncfl = {cfl}\n"


# ---------------------------------------------------------------------------------------------
# defaults and bounds


def test_an_almost_empty_spec_gets_the_documented_defaults(tmp_path):
    """Without [sweep]: the title `Sweep <file stem>`, warm-up on, the default cell cap; an accuracy table is
    labelled `grid`, a scene table `scene` with no variants (the config's own), the config's own cells and step,
    seed 0, nothing rendered, frames/particles/preset unset."""
    spec = load(tmp_path, ACC + SCENE, "my_runs.toml")
    assert (spec.title, spec.warmup, spec.max_cells) == ("Sweep my_runs", True, DEFAULT_MAX_CELLS)
    (a,), (s,) = spec.accuracy, spec.scenes
    assert (a.cases, a.cells, a.cfl, a.label) == (("spin",), (16,), (0.4,), "grid")
    assert (s.configs, s.variants, s.cells, s.steps, s.seeds, s.overrides) == (
        ("bread",),
        (),
        (None,),
        (None,),
        (0,),
        (),
    )
    assert (s.frames, s.particles, s.preset, s.render, s.label) == (None, None, None, False, "scene")


def test_each_bound_is_inclusive_where_documented(tmp_path):
    """The largest and smallest allowed values pass: cells 4 and 4096, CFL and dt 1 (their ranges are (0, 1]),
    seed 0 and 2³¹ − 1, frames 1 and 1,000,000, particles 1, max_cells 1; a preset given as a one-element list
    is that preset."""
    spec = load(tmp_path, "[sweep]\nmax_cells = 1\n" + acc("[4, 4096]", "[1.0, 1e-9]"))
    assert spec.max_cells == 1 and spec.accuracy[0].cells == (4, 4096) and spec.accuracy[0].cfl == (1.0, 1e-9)
    text = SCENE + f'dt = [1.0]\ncfl = [1]\nseed = [0, {2**31 - 1}]\nframes = 1\nparticles = 1\npreset = ["paper"]\n'
    s = load(tmp_path, text).scenes[0]
    assert s.steps == (("dt", 1.0), ("cfl", 1.0)) and s.seeds == (0, 2**31 - 1)
    assert (s.frames, s.particles, s.preset) == (1, 1, "paper")
    assert load(tmp_path, SCENE + "frames = 1_000_000\n").scenes[0].frames == 1_000_000


@pytest.mark.parametrize(
    "text, message",
    [
        (
            acc("[3]"),
            "accuracy[0].cells value 3 must be an integer in [4, 4096]; e.g. cells = [16, 32] for Δx = 1/16, 1/32.",
        ),
        (acc("[4097]"), "accuracy[0].cells value 4097 must be an integer in [4, 4096]"),
        (acc("[16.0]"), "accuracy[0].cells value 16.0 must be an integer in [4, 4096]"),
        (acc("[true]"), "accuracy[0].cells value True must be an integer in [4, 4096]"),
        (acc(cfl="0"), "accuracy[0].cfl value 0 must be a number in (0, 1]; e.g. cfl = [0.2, 0.4]."),
        (acc(cfl="1.0000001"), "accuracy[0].cfl value 1.0000001 must be a number in (0, 1]"),
        (acc(cfl="nan"), "accuracy[0].cfl value nan must be a number in (0, 1]"),
        (acc(cfl='"0.4"'), "accuracy[0].cfl value '0.4' must be a number in (0, 1]"),
        (SCENE + "dt = [2.0]\n", "scene[0].dt value 2.0 must be a number in (0, 1]; e.g. dt = [1e-4, 5e-5]."),
        (SCENE + "cfl = [0.0]\n", "scene[0].cfl value 0.0 must be a number in (0, 1]; e.g. cfl = [0.2, 0.4]."),
        (SCENE + "seed = -1\n", "scene[0].seed value -1 must be an integer in [0, 2147483647]; e.g. seed = [0, 1, 2]."),
        (SCENE + f"seed = {2**31}\n", "scene[0].seed value 2147483648 must be an integer in [0, 2147483647]"),
        (SCENE + "frames = 0\n", "scene[0].frames value 0 must be an integer in [1, 1000000]; e.g. frames = 10."),
        (SCENE + "frames = 1_000_001\n", "scene[0].frames value 1000001 must be an integer in [1, 1000000]"),
        (SCENE + "particles = 0\n", "scene[0].particles value 0 must be an integer in [1, 100000000]"),
        (SCENE + "cells = [2]\n", "scene[0].cells value 2 must be an integer in [4, 4096]; e.g. cells = [32, 64]."),
        (
            "[sweep]\nmax_cells = 0\n" + ACC,
            "sweep.max_cells = 0 must be a positive integer; write it like max_cells = 20000.",
        ),
        ("[sweep]\nmax_cells = 2.5\n" + ACC, "sweep.max_cells = 2.5 must be a positive integer"),
    ],
)
def test_a_value_just_outside_its_bounds_is_refused_naming_the_range(tmp_path, text, message):
    """One past each bound (and a float, boolean, NaN or quoted number where a number of a kind belongs) is one
    sentence naming the key, the value, the range and an example."""
    assert refused(tmp_path, text).startswith(message)


# ---------------------------------------------------------------------------------------------
# malformed tables and values


@pytest.mark.parametrize(
    "text, message",
    [
        ("sweep = 3\n" + ACC, "sweep must be a table; write it as [sweep] with title and warmup keys."),
        ("[sweep]\ntitle = 3\n" + ACC, 'sweep.title = 3 must be a string; write title = "My sweep".'),
        ("accuracy = 3\n", "accuracy must be an array of tables; write each one as [[accuracy]]."),
        ("scene = [1]\n", "scene must be an array of tables; write each one as [[scene]]."),
        (acc(case="[]"), "accuracy[0].case is an empty list; give at least one value or remove the key."),
        (ACC + 'label = "a|b"\n', 'accuracy[0].label = \'a|b\' must be a short name without "|", "," or newlines.'),
        (ACC + 'label = "a,b"\n', "accuracy[0].label = 'a,b' must be a short name"),
        (ACC + 'label = " "\n', "accuracy[0].label = ' ' must be a short name"),
        (SCENE + "label = 3\n", "scene[0].label = 3 must be a short name"),
        (
            '[[scene]]\nvariant = "full"\n',
            'scene[0].config is missing; add it, e.g. config = ["bread"] (built-in names or paths).',
        ),
        ('[[scene]]\nconfig = ["bread", ""]\n', "scene[0].config value '' must be a config name or path."),
        ("[[scene]]\nconfig = 3\n", "scene[0].config value 3 must be a config name or path."),
        (SCENE + "material = 3\n", "scene[0].material must be a table: [scene.material] E = [...]."),
        (SCENE + "set = 3\n", 'scene[0].set must be a table: [scene.set] "sim.cfl" = [...].'),
        (
            SCENE + "[scene.set.sim]\ndt = [1e-4]\n",
            'scene[0].set.sim is a table; quote the dotted key: "sim.field" = [...].',
        ),
        (SCENE + 'render = "yes"\n', "scene[0].render = 'yes' must be true or false."),
        (
            SCENE + 'preset = "big"\n',
            "scene[0].preset value 'big' is not one of small, paper; choose from small, paper; "
            'e.g. preset = "small".',
        ),
        (SCENE + 'preset = "smal"\n', "scene[0].preset value 'smal' is not one of small, paper; did you mean 'small'?"),
        (
            SCENE + "zzzzz = 1\n",
            "scene[0].zzzzz is not a sweep-spec key; valid keys here: label, config, variant, cells, dt, cfl, seed, ",
        ),
        ("[sweep]\nwarmupp = true\n" + ACC, "sweep.warmupp is not a sweep-spec key; did you mean 'warmup'?"),
    ],
)
def test_a_malformed_table_or_value_is_one_sentence_with_its_fix(tmp_path, text, message):
    """Tables that are not tables, empty lists, labels that would break the tables' columns, configs that are no
    names, a set table that should have been a quoted dotted key, render that is not a boolean, a preset that does
    not exist: each is one sentence naming the key and the fix."""
    assert refused(tmp_path, text).startswith(message)


def test_a_spec_that_is_no_utf8_or_names_nothing_is_refused(tmp_path):
    """A spec file that is not UTF-8 says so with the decoder's reason; a name that is neither a file nor a
    built-in spec lists the built-in specs; a built-in name is found with or without .toml."""
    (tmp_path / "latin.toml").write_bytes(b'[sweep]\ntitle = "caf\xe9"\n')
    with pytest.raises(
        ConfigError, match=r"latin\.toml: cannot be read as UTF-8 text \(.*byte 0xe9.*\); check the file\."
    ):
        load_spec(tmp_path / "latin.toml")
    with pytest.raises(ConfigError) as info:
        load_spec("no_such_sweep")
    assert str(info.value).startswith(
        "no_such_sweep: no such sweep spec; pass a path to a TOML file or a built-in name ("
    )
    assert "accuracy" in str(info.value)
    assert load_spec("accuracy").path == load_spec("accuracy.toml").path == SPEC_DIR / "accuracy.toml"
