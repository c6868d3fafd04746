"""Pinned rule of a [[scene]] table's one-value keys (`fracture_gs.sweep.spec.load_spec`): frames, particles and
preset take one value per table, written plainly or as a one-element list (the same block either way); a list of
any other length, the empty one included, is refused with the same sentence naming the key, the list's length and
the fix, and a one-element list is still checked like the plain value.

Unit-level: specs are parsed, never expanded.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.sweep.spec import load_spec

PLAIN = {"frames": ("7", 7), "particles": ("500", 500), "preset": ('"paper"', "paper")}


def _block(tmp_path, line: str):
    path = tmp_path / "s.toml"
    path.write_text(f'[[scene]]\nconfig = "bread"\n{line}\n')
    return load_spec(path).scenes[0]


def _message(tmp_path, line: str) -> str:
    with pytest.raises(ConfigError) as info:
        _block(tmp_path, line)
    return str(info.value).split(": ", 1)[1]


@pytest.mark.parametrize("key", list(PLAIN))
def test_a_one_element_list_is_the_plain_value(tmp_path, key):
    """`frames = [7]` is `frames = 7` (and so for particles and preset): the block holds the value itself."""
    text, value = PLAIN[key]
    assert getattr(_block(tmp_path, f"{key} = {text}"), key) == value
    assert getattr(_block(tmp_path, f"{key} = [{text}]"), key) == value


@pytest.mark.parametrize("key", list(PLAIN))
@pytest.mark.parametrize("count", [0, 2, 3])
def test_a_list_of_any_other_length_is_one_sentence_with_its_length(tmp_path, key, count):
    """An empty list, or one of 2 or 3 values, is refused naming scene[0].<key>, the length and the fix (one value,
    or one [[scene]] table per value) — the empty list gets this sentence too, not the generic empty-list one."""
    text = PLAIN[key][0]
    items = [text.replace("7", str(7 + i)).replace("500", str(500 + i)) for i in range(count)]
    if key == "preset":
        items = ['"small"', '"paper"', '"small"'][:count]
    assert _message(tmp_path, f"{key} = [{', '.join(items)}]") == (
        f"scene[0].{key} takes one value, not a list of {count}; give one value, or one [[scene]] table per value."
    )


def test_a_one_element_list_is_checked_like_the_value(tmp_path):
    """`frames = [0]` is refused by the frames range, and `preset = ["big"]` by the preset names, exactly as the
    plain values would be."""
    assert _message(tmp_path, "frames = [0]") == _message(tmp_path, "frames = 0")
    assert _message(tmp_path, 'preset = ["big"]') == _message(tmp_path, 'preset = "big"')
