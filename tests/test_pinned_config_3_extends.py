"""Pinned rules of a config's `extends` key (`fracture_gs.io.config.files`): where the named base is looked up
(beside the extending file first, with or without `.toml`, then the built-ins), that a splat file is refused as a
base with a sentence that says what to write instead (not "is not UTF-8 text"), and the messages for a value that
is not a name or names nothing.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict, load_config

CAPTURES = Path(__file__).parent / "data" / "captures"


def refusal(fn) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        fn()
    assert info.value.field == "extends"
    return info.value


def test_a_splat_file_as_base_is_refused_saying_to_use_scene(tmp_path, monkeypatch):
    """`extends` names a config; a splat file (recognised by its suffix, or by its content without one) is a
    scene: it is refused naming the value and the fix (scene = ..., extends = "capture"), from a file beside the
    config and from the dict API alike, instead of being read as TOML."""
    shutil.copyfile(CAPTURES / "donut_5k.ply", tmp_path / "scan.ply")
    shutil.copyfile(CAPTURES / "donut_5k.ply", tmp_path / "scan_without_suffix")
    for value in ("scan.ply", "scan_without_suffix"):
        (tmp_path / "mine.toml").write_text(f'extends = "{value}"\n')
        err = refusal(lambda: load_config(tmp_path / "mine.toml"))
        assert str(err).endswith(
            f"mine.toml: extends = '{value}' names a splat file, which is a scene, not a config; write scene = "
            f"'{value}' instead (with extends = \"capture\" for the capture settings)."
        )
    monkeypatch.chdir(tmp_path)
    err = refusal(lambda: config_from_dict({"extends": "scan.ply"}))
    assert "extends = 'scan.ply' names a splat file" in str(err) and "not UTF-8" not in str(err)


def test_a_base_beside_the_file_comes_before_a_builtin_of_the_same_name(tmp_path):
    """`extends = "bread"` takes bread.toml beside the extending file when there is one (with or without the
    .toml in the value), and the built-in bread config otherwise."""
    (tmp_path / "mine.toml").write_text('extends = "bread"\nname = "mine"\n')
    assert load_config(tmp_path / "mine.toml").frames == load_config("bread").frames == 90
    (tmp_path / "bread.toml").write_text('extends = "recontact"\nframes = 7\n')
    assert load_config(tmp_path / "mine.toml").frames == 7
    (tmp_path / "mine.toml").write_text('extends = "bread.toml"\nname = "mine"\n')
    assert load_config(tmp_path / "mine.toml").frames == 7


@pytest.mark.parametrize("value", ["", 3, ["bread"]])
def test_extends_must_be_a_non_empty_name(tmp_path, value):
    """`extends` takes one config name or path as a string: an empty string, a number or an array is refused with
    an example."""
    err = refusal(lambda: config_from_dict({"extends": value}))
    assert str(err) == '<dict>: extends must be a config name or path string; write it like extends = "bread".'


def test_a_base_that_names_nothing_lists_the_builtins(tmp_path):
    """A base that is neither beside the file nor a built-in is refused naming the value, the two places it may
    be, and the built-in names."""
    (tmp_path / "mine.toml").write_text('extends = "breadd"\n')
    err = refusal(lambda: load_config(tmp_path / "mine.toml"))
    assert "extends = 'breadd' names no config file; use a path relative to this file or a built-in name (" in str(err)
    assert "bread, " in str(err) and "recontact" in str(err)
