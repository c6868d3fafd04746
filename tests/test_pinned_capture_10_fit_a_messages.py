"""Pinned rules of how a cameras.json error names its view and the wrong value (`capture.fit`), round ten:

- a view is named by its `img_name` on one line: runs of whitespace (newlines, tabs) become one space, the ends
  are stripped, and a name of more than 40 characters is cut to its first 39 and an ellipsis (40 in all); a
  name of exactly 40 is shown whole; an empty or blank name adds nothing;
- a wrong value is described by its JSON kind: "the boolean true/false", "the number <repr>" (at most 40
  characters of it), "the non-finite number nan/inf" (and a JSON integer too large for a float), "the string
  '<first 40 characters>'", "a list of <n>", "an object", "null"; any other Python type by its type name.

Each rule is checked directly and through the message read_cameras raises (what the user reads).
"""

from __future__ import annotations

import json

import pytest
from badinput import one_line

from fracture_gs.capture.fit import _describe, _short_name, read_cameras
from fracture_gs.errors import SceneError

ALPHABET = "abcdefghijklmnopqrstuvwxyz0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ"  # 62 distinct characters


def view(**over) -> dict:
    good = {
        "img_name": "v0",
        "position": [1.0, 2.0, 3.0],
        "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "fx": 500.0,
        "fy": 500.0,
        "width": 640,
        "height": 480,
    }
    return {**good, **over}


def refusal(tmp_path, text: str) -> str:
    path = tmp_path / "cameras.json"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    return one_line(info.value)


# ---------------------------------------------------------------------------------------------------------------
# a view's name


@pytest.mark.parametrize("n", [1, 39, 40])
def test_a_name_of_at_most_40_characters_is_shown_whole(n):
    """Rule: a name of up to 40 characters, 40 included, is shown as written."""
    assert _short_name(ALPHABET[:n]) == ALPHABET[:n]


@pytest.mark.parametrize("n", [41, 42, 62])
def test_a_longer_name_is_cut_to_39_characters_and_an_ellipsis(n):
    """Rule: a name of more than 40 characters is shown as its first 39 characters and "…", 40 in all."""
    short = _short_name(ALPHABET[:n])
    assert short == ALPHABET[:39] + "…"
    assert len(short) == 40


def test_a_name_is_shown_on_one_line_with_single_spaces():
    """Rule: newlines, tabs and runs of spaces in a name become single spaces and its ends are stripped, before
    the 40-character cap is applied (so 40 characters of collapsed text are shown whole)."""
    assert _short_name("  left\n\tside   view \r\n") == "left side view"
    padded = "  " + "a" * 20 + "\n\n\n" + "b" * 19 + "\t "  # 40 characters once collapsed, 46 as written
    assert _short_name(padded) == "a" * 20 + " " + "b" * 19


@pytest.mark.parametrize(
    "name, shown",
    [
        (ALPHABET[:40], ALPHABET[:40]),
        (ALPHABET[:41], ALPHABET[:39] + "…"),
        ("front\nview", "front view"),
    ],
)
def test_the_message_names_the_view_as_shortened(tmp_path, name, shown):
    """Rule: read_cameras' message names the file, the view's index and its shortened name in parentheses."""
    path = tmp_path / "cameras.json"
    msg = refusal(tmp_path, json.dumps([view(), view(img_name=name, fx=0)]))
    assert msg.startswith(f"{path}: camera 1 ({shown}): fx must be a positive focal length in pixels, not ")


@pytest.mark.parametrize("name", ["", "  \n\t "])
def test_a_blank_name_adds_no_parentheses(tmp_path, name):
    """Rule: a view whose name is empty or only whitespace is named by its index alone."""
    path = tmp_path / "cameras.json"
    msg = refusal(tmp_path, json.dumps([view(img_name=name, fy=-1)]))
    assert msg.startswith(f"{path}: camera 0: fy must be a positive focal length in pixels, not the number -1;")


# ---------------------------------------------------------------------------------------------------------------
# a wrong value


@pytest.mark.parametrize(
    "value, text",
    [
        (True, "the boolean true"),
        (False, "the boolean false"),
        (0, "the number 0"),
        (-3, "the number -3"),
        (2.5, "the number 2.5"),
        (10**50, "the number " + "1" + "0" * 39),  # repr cut to 40 characters
        (-(10**50), "the number -" + "1" + "0" * 38),
        (float("nan"), "the non-finite number nan"),
        (float("-inf"), "the non-finite number -inf"),
        (10**400, "the non-finite number " + "1" + "0" * 39),  # too large for a float; repr cut to 40
        ("500", "the string '500'"),
        ("", "the string ''"),
        (ALPHABET[:40], f"the string '{ALPHABET[:40]}'"),
        (ALPHABET, f"the string '{ALPHABET[:40]}'"),
        ([], "a list of 0"),
        ([1.0, 2.0], "a list of 2"),
        ({}, "an object"),
        ({"a": 1}, "an object"),
        (None, "null"),
        ((1, 2), "tuple"),
        (b"x", "bytes"),
    ],
)
def test_describe_names_the_json_kind_of_a_wrong_value(value, text):
    """Rule: a wrong value is named by its JSON kind (booleans before numbers, though bool is an int; a number
    by at most 40 characters of its repr, and as non-finite when it is NaN, inf or too large for a float; a
    string by its first 40 characters); any other Python type by its type name."""
    assert _describe(value) == text


@pytest.mark.parametrize(
    "json_value, text",
    [
        ("true", "the boolean true"),
        ("0", "the number 0"),
        ("-2.5", "the number -2.5"),
        ('"500"', "the string '500'"),
        (json.dumps(ALPHABET), f"the string '{ALPHABET[:40]}'"),
        ("[500]", "a list of 1"),
        ('{"f": 500}', "an object"),
        ("null", "null"),
        ("NaN", "the non-finite number nan"),
        ("1e400", "the non-finite number inf"),
    ],
)
def test_a_wrong_focal_length_is_described_in_the_message(tmp_path, json_value, text):
    """Rule: the message for a wrong fx names the file, the view, the key and the value as described above."""
    path = tmp_path / "cameras.json"
    good = json.dumps(view(img_name="cam")).replace('"fx": 500.0', f'"fx": {json_value}')
    msg = refusal(tmp_path, f"[{good}]")
    assert msg.startswith(f"{path}: camera 0 (cam): fx must be a positive focal length in pixels, not {text}; ")


def test_a_wrong_file_and_a_wrong_view_are_described(tmp_path):
    """Rule: a cameras.json that is not a list, and a view that is not an object, are described by kind too."""
    path = tmp_path / "cameras.json"
    msg = refusal(tmp_path, '{"views": []}')
    assert msg.startswith(f"{path}: cameras.json must be a non-empty list of views, not an object; ")
    msg = refusal(tmp_path, "[null]")
    assert msg.startswith(f"{path}: camera 0 is null, not an object with position, rotation, fx, fy, width and ")
    msg = refusal(tmp_path, json.dumps([view(), 7]))
    assert msg.startswith(f"{path}: camera 1 is the number 7, not an object")
    msg = refusal(tmp_path, json.dumps([view(position=[0.0, False, 1.0])]))
    assert "position holds the boolean false; it must be 3 finite numbers" in msg
