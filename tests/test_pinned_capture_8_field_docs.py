"""Pinned rule of the field documentation the starter TOML comments with (`capture.starter.field_docs`), round
eight: a field's documentation is the string literal right under its annotated assignment in a class of config.py,
its whitespace folded to single spaces. Nothing else is: not a number, `...` or a call written under a field, not
the string under a plain (unannotated) assignment, not one under a module-level name; a field with nothing under
it has no entry, and two classes' fields of one name are told apart.

The source read is a hand-written module (never imported: only parsed), put in place of config.py.
"""

from __future__ import annotations

import textwrap
import types

import pytest

from fracture_gs.capture import starter

SOURCE = textwrap.dedent(
    '''
    """A config module."""

    from dataclasses import dataclass


    @dataclass
    class Alpha:
        """The class docstring is not a field's."""

        a: int = 1
        """First   field,
        over two lines."""
        b: float = 2.0
        c: str = "x"
        """Third [m]."""
        d: int = 4
        5
        e: int = 5
        ...
        f: int = 6
        sorted([])
        g = 7
        """A plain assignment's string."""
        h: int = 8
        """Last."""


    class Beta:
        a: int = 1
        """Beta's own a."""


    X: int = 1
    """Module level."""
    '''
)


@pytest.fixture
def fake_config(tmp_path, monkeypatch):
    path = tmp_path / "fake_config.py"
    path.write_text(SOURCE, encoding="utf-8")
    module = types.ModuleType("fake_config")
    module.__file__ = str(path)
    monkeypatch.setattr(starter, "config_module", module)
    starter.field_docs.cache_clear()
    yield
    starter.field_docs.cache_clear()  # the next caller reads the real config.py again


def test_only_a_string_right_under_an_annotated_field_documents_it(fake_config):
    """Alpha.a, Alpha.c, Alpha.h and Beta.a are documented (a's two lines folded into one); Alpha.b (nothing
    under it), d (a number under it), e (`...`), f (a call), g (not annotated) and the module-level X are not."""
    assert starter.field_docs() == {
        ("Alpha", "a"): "First field, over two lines.",
        ("Alpha", "c"): "Third [m].",
        ("Alpha", "h"): "Last.",
        ("Beta", "a"): "Beta's own a.",
    }


def test_the_real_config_documents_its_fields_again_afterwards():
    """After the fake module is gone the cache holds the real config.py's fields (capture.size among them) and
    none of the fake's."""
    docs = starter.field_docs()
    assert ("CaptureConfig", "size") in docs and ("Alpha", "a") not in docs
