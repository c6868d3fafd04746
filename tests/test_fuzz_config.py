"""Property: whatever TOML a user writes, `load_config` returns a valid config whose every float is finite
and which validates again after a round trip, or raises `ConfigError` naming the file — never another
exception. Three kinds of input: random documents over every config key (every type, NaN, inf, huge,
negative, unicode, wrong shapes, unknown keys), one known-bad value planted in a built-in config (a
non-finite float, a wrong type, an unknown key: each must be refused, so no silent acceptance), and
byte-level mutations of a built-in config's text (BOM, invalid UTF-8, deleted or inserted characters)."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import typing

import pytest
from fuzzutil import Tally, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

from fracture_gs.config import SceneConfig
from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict, dump_config, load_config, validate
from fracture_gs.io.config.dump import config_to_dict


def schema(cls=SceneConfig, prefix="") -> dict[str, typing.Any]:
    """Every leaf key of the config (dotted) and its declared type."""
    out = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            out.update(schema(tp, f"{prefix}{f.name}."))
        else:
            out[prefix + f.name] = tp
    return out


KEYS = schema()
BASE = config_to_dict(load_config("bread"))
UNICODE = st.text(st.characters(exclude_categories=["Cs"]), max_size=12)
FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1.0, 1e300, 0.5, 1e6]),
)
SCALARS = st.one_of(st.integers(-(2**63), 2**63 - 1), FLOATS, st.booleans(), UNICODE)
VALUES = st.one_of(SCALARS, st.lists(st.one_of(FLOATS, st.integers(-5, 5)), max_size=5), st.lists(SCALARS, max_size=3))


def toml_value(v) -> str:
    """An independent TOML writer for the fuzz documents (NaN and inf as TOML's nan / inf)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


def to_toml(doc: dict) -> str:
    """Nested dict → TOML text (tables as [a.b] headers, lists of dicts as [[a]])."""
    lines: list[str] = []

    def emit(table: dict, path: str) -> None:
        for k, v in table.items():
            if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v)):
                lines.append(f"{json.dumps(k, ensure_ascii=False)} = {toml_value(v)}")
        for k, v in table.items():
            sub = f"{path}.{json.dumps(k, ensure_ascii=False)}" if path else json.dumps(k, ensure_ascii=False)
            if isinstance(v, dict):
                lines.append(f"[{sub}]")
                emit(v, sub)
            elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
                for item in v:
                    lines.append(f"[[{sub}]]")
                    emit(item, sub)

    emit(doc, "")
    return "\n".join(lines) + "\n"


def put(doc: dict, dotted: str, value) -> None:
    node, keys = doc, dotted.split(".")
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
        if not isinstance(node, (dict, list)):
            return
    if isinstance(node, dict):
        node[keys[-1]] = value


def float_leaves(doc, prefix=""):
    """Dotted paths of every float or float-vector leaf of a config dict (lists of tables included)."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from float_leaves(v, f"{prefix}.{k}" if prefix else k)
    elif isinstance(doc, list) and doc and all(isinstance(v, dict) for v in doc):
        for i, v in enumerate(doc):
            yield from float_leaves(v, f"{prefix}.{i}")
    elif isinstance(doc, float) or (isinstance(doc, list) and doc and isinstance(doc[0], float)):
        yield prefix


FLOAT_LEAVES = list(float_leaves(BASE))


def typed_value(tp):
    """A value of the declared type (often valid, sometimes out of range): explores the accepting side."""
    if typing.get_origin(tp) is typing.Literal:
        return st.sampled_from(typing.get_args(tp))
    if typing.get_origin(tp) is typing.Union:
        tp = next(a for a in typing.get_args(tp) if a is not type(None))
    if tp is bool:
        return st.booleans()
    if tp is int:
        return st.integers(-2, 100)
    if tp is float:
        return st.floats(-1.0, 1e4, allow_nan=False)
    if typing.get_origin(tp) is tuple:
        return st.lists(st.floats(-2.0, 2.0, allow_nan=False), min_size=3, max_size=3)
    return VALUES


@st.composite
def random_document(draw):
    doc: dict = {"extends": "bread"} if draw(st.booleans()) else {}
    for key in draw(st.lists(st.sampled_from(sorted(KEYS)), max_size=8, unique=True)):
        put(doc, key, draw(typed_value(KEYS[key]) if draw(st.booleans()) else VALUES))
    for _ in range(draw(st.integers(0, 2))):
        put(doc, draw(st.sampled_from(["", "sim.", "render.", "topology."])) + draw(UNICODE.filter(bool)), draw(VALUES))
    if draw(st.booleans()):
        doc["sim"] = doc.get("sim") if isinstance(doc.get("sim"), dict) else {}
        doc["sim"]["boundaries"] = [
            {"type": draw(st.sampled_from(["plane", "cuboid", "region", "nope"])), "lower": draw(VALUES)}
        ]
    return doc


@st.composite
def planted(draw):
    """A built-in config with one value that must be refused, and what was planted."""
    doc = copy.deepcopy(BASE)
    kind = draw(st.sampled_from(["nonfinite", "wrong_type", "unknown_key", "negative_count", "beyond_bound"]))
    if kind == "nonfinite":
        path = draw(st.sampled_from(FLOAT_LEAVES))
        bad = draw(st.sampled_from([math.nan, math.inf, -math.inf]))
        node, keys = doc, path.split(".")
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        old = node[keys[-1]]
        node[keys[-1]] = [bad, *old[1:]] if isinstance(old, list) else bad
    elif kind == "wrong_type":
        path = draw(st.sampled_from(["frames", "frame_dt", "sim.dx", "render.width", "material.E", "sim.gravity"]))
        put(doc, path, draw(st.sampled_from(["ten", [1, 2], {"a": 1}, True])))
    elif kind == "unknown_key":
        path = draw(st.sampled_from(["", "sim.", "render.", "topology.", "material."])) + "zz_" + draw(UNICODE)
        put(doc, path, 1)
    elif kind == "beyond_bound":  # round five: finite values no user can mean (fps, gravity, a CFL-bound modulus)
        path = draw(st.sampled_from(["render.fps", "sim.gravity", "material.E"]))
        if path == "render.fps":
            put(doc, path, draw(st.integers(1001, 10**9)))
        elif path == "sim.gravity":
            put(doc, path, [0.0, 0.0, draw(st.sampled_from([-1, 1])) * draw(st.floats(1.001e4, 1e300))])
        else:
            put(doc, path, draw(st.floats(1e25, 1e300)))
    else:
        path = draw(st.sampled_from(["frames", "render.width", "render.fps", "topology.min_particles", "particles"]))
        put(doc, path, draw(st.sampled_from([0, -1, -(2**40)])))
    return kind, path, doc


TEXT = dump_config(load_config("bread")).encode()


@st.composite
def mutated_text(draw):
    data = bytearray(TEXT)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["delete", "insert", "replace", "truncate", "bom", "latin1"]))
        pos = draw(st.integers(0, len(data)))
        if op == "delete":
            del data[pos : pos + draw(st.integers(1, 20))]
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif op == "replace" and pos < len(data):
            data[pos] = draw(st.integers(0, 255))
        elif op == "truncate":
            del data[pos:]
        elif op == "bom":
            data[0:0] = b"\xef\xbb\xbf"
        elif op == "latin1":
            data[pos:pos] = "é".encode("latin-1")
    return bytes(data)


def check_clean(cfg: SceneConfig) -> None:
    """Never NaN in an output: a loaded config has only finite floats and survives a dump/load round trip."""
    for path in float_leaves(config_to_dict(cfg)):
        node = config_to_dict(cfg)
        for k in path.split("."):
            node = node[int(k)] if isinstance(node, list) else node[k]
        assert all(math.isfinite(v) for v in (node if isinstance(node, list) else [node])), path
    validate(config_from_dict(config_to_dict(cfg), "round trip"), "round trip")


def outcome(tally: Tally, category: str, path, must_fail: bool = False) -> None:
    try:
        cfg = load_config(path)
    except ConfigError as err:
        assert str(err).strip() and ("\n" not in str(err)), err
        tally.add(category, "our error")
    except Exception:
        tally.add(category, "traceback")
        raise
    else:
        if must_fail:
            tally.add(category, "silent acceptance")
            raise AssertionError(f"{category}: a config with a planted bad value loaded")
        check_clean(cfg)
        tally.add(category, "clean load")


@pytest.mark.slow
@pytest.mark.usefixtures("one_thread")
def test_fuzz_config(tmp_path_factory, capsys):
    tally = Tally("config")
    folder = tmp_path_factory.mktemp("fuzz_config")
    path = folder / "fuzz.toml"

    @fuzz_settings(400)
    @given(random_document())
    def documents(doc):
        path.write_text(to_toml(doc), encoding="utf-8")
        outcome(tally, "random document", path)

    @fuzz_settings(300)
    @given(planted())
    def planted_values(case):
        kind, _, doc = case
        path.write_text(to_toml(doc), encoding="utf-8")
        outcome(tally, f"planted {kind}", path, must_fail=True)

    @fuzz_settings(300)
    @given(mutated_text())
    def mutations(data):
        path.write_bytes(data)
        outcome(tally, "mutated text", path)

    documents()
    planted_values()
    mutations()
    tally.report(capsys)
    assert tally.total() >= 1000 and tally.total("traceback") == 0 and tally.total("silent acceptance") == 0
    assert tally.counts["random document"]["clean load"] > 0 and tally.counts["mutated text"]["our error"] > 0
