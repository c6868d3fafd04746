"""Pinned rules of the starter TOML's field documentation (`capture.starter.field_docs`), round three: a config
field's documentation is the string literal right under its annotated line, whitespace folded to single
spaces; class docstrings, plain assignments, methods and undocumented fields give none; and every key the
starter writes, in every table, has one.

`field_docs` is cached: each test clears the cache, so it reads the source itself (and the next caller reads
the real config module again).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys

import pytest

from fracture_gs.capture import starter

SYNTHETIC = '''
"""A module docstring."""
from dataclasses import dataclass

TOP: int = 1
"""Not in a class: no field."""


@dataclass
class Lamp:
    """The class docstring is not a field's."""

    watts: float = 60.0
    """Power drawn
       [W],   folded    onto one line."""
    colour: str = "warm"
    hours: int = 0
    """Hours lit."""
    plain = 3
    """Under a plain assignment: no field."""

    def on(self) -> bool:
        """A method's docstring."""
        return True


class Shade:
    opacity: float = 0.5
    """Light let through [0–1]."""
'''


@pytest.fixture
def fresh_docs():
    starter.field_docs.cache_clear()
    yield starter.field_docs
    starter.field_docs.cache_clear()


def test_the_string_under_an_annotated_field_is_its_documentation(tmp_path, monkeypatch, fresh_docs):
    """In a module of two classes: the strings right under `watts`, `hours` and `opacity` are their docs (the
    first folded onto one line); `colour` (followed by another field), `plain` (not annotated), the class and
    method docstrings and a module-level annotated name give none."""
    path = tmp_path / "synthetic_config.py"
    path.write_text(SYNTHETIC)
    spec = importlib.util.spec_from_file_location("synthetic_config", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "synthetic_config", module)
    spec.loader.exec_module(module)
    monkeypatch.setattr(starter, "config_module", module)
    assert fresh_docs() == {
        ("Lamp", "watts"): "Power drawn [W], folded onto one line.",
        ("Lamp", "hours"): "Hours lit.",
        ("Shade", "opacity"): "Light let through [0–1].",
    }


def test_every_key_the_starter_writes_is_documented(fresh_docs):
    """Every field of every class whose table the starter TOML writes (scene, sim, contact, boundaries, material,
    material map, topology, render, camera, capture) has its docstring, on one line: a real example is the
    camera's `up`, "World up vector."."""
    docs = fresh_docs()
    missing = [
        (cls.__name__, f.name)
        for classes in starter.TABLES.values()
        for cls in classes
        for f in dataclasses.fields(cls)
        if not docs.get((cls.__name__, f.name))
    ]
    assert missing == []
    assert docs[("CameraConfig", "up")] == "World up vector."
    assert all("\n" not in d and "  " not in d for d in docs.values())
