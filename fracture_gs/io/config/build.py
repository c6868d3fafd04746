"""Building the config dataclasses from TOML-shaped dicts: keys, types and `Literal` choices.

Strict: an unknown key gets the closest valid name, a value of the wrong type or outside a
`Literal` field's choices gets one sentence naming the file, the dotted field and the fix.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import typing
from typing import Any, Iterable, Literal, Sequence, Union

from ...config import (
    BOUNDARY_TYPES,
    CaptureConfig,
    MaterialMapEntry,
    MaterialRegion,
    OraclePlane,
    PlaneBoundary,
    SceneConfig,
    SimConfig,
    TopologyConfig,
)
from ...errors import ConfigError
from .dump import to_plain_value, toml_value


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def describe(value: Any) -> str:
    """How a wrong value reads in a message."""
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (list, tuple)):
        return f"an array of {len(value)} item{'s' if len(value) != 1 else ''}"
    return f"a {type(value).__name__}"


def _type_name(tp: Any) -> str:
    """Human description of an annotation, for 'must be ...'."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Union:
        return _type_name(next(a for a in args if a is not type(None)))
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in args)
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if origin is tuple:
        inner = _type_name(args[0])
        inner = {"a number": "numbers", "an integer": "integers"}.get(inner, inner.replace("an array", "arrays"))
        return f"an array of {len(args)} {inner}"
    if dataclasses.is_dataclass(tp):
        return "a table"
    return "an array"


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """Resolved field annotations of a config dataclass (cached)."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _example(cls: type, key: str) -> str:
    """`key = <default>` written as TOML, used as the fix in type errors."""
    f = next(f for f in dataclasses.fields(cls) if f.name == key)
    default = f.default if f.default is not dataclasses.MISSING else None
    if default is None:
        return ""
    return f"; write it like {key} = {toml_value(to_plain_value(default))}"


def _type_error(src: str, dotted: str, tp: Any, value: Any, cls: type, key: str) -> ConfigError:
    hint = _example(cls, key)
    if isinstance(value, str) and typing.get_origin(tp) is not tuple and tp in (float, int):
        hint = f"; write the number without quotes, e.g. {key} = {value.strip()}" if _is_number_text(value) else hint
    return ConfigError(src, dotted, f"{dotted} must be {_type_name(tp)}, not {describe(value)}{hint or ''}.")


def _is_number_text(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _convert(value: Any, tp: Any, dotted: str, src: str, cls: type, key: str) -> Any:
    """Check `value` against annotation `tp` and convert (arrays → tuples, ints → floats)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Union:
        if value is None:
            return None
        return _convert(value, next(a for a in args if a is not type(None)), dotted, src, cls, key)
    if origin is Literal:
        if not isinstance(value, str):
            raise _type_error(src, dotted, tp, value, cls, key)
        if value not in args:
            same = [str(a) for a in args if str(a).lower() in (value.strip().lower(), "+" + value.strip().lower())]
            close = same or difflib.get_close_matches(value, [str(a) for a in args], n=1)  # 'y' means '+y', not '-y'
            fix = f"did you mean {close[0]!r}?" if close else f"use one of {', '.join(map(str, args))}."
            raise ConfigError(src, dotted, f"{dotted} = {value!r} is not one of {', '.join(map(str, args))}; {fix}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _type_error(src, dotted, tp, value, cls, key)
        return float(value)
    if tp is int or tp is bool or tp is str:
        if type(value) is not tp:
            raise _type_error(src, dotted, tp, value, cls, key)
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise _type_error(src, dotted, tp, value, cls, key)
        return tuple(_convert(v, a, f"{dotted}[{i}]", src, cls, key) for i, (v, a) in enumerate(zip(value, args)))
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _build(tp, value, dotted, src)
    raise _type_error(src, dotted, tp, value, cls, key)


def _unknown_key(src: str, prefix: str, key: str, valid: Sequence[str]) -> ConfigError:
    """Unknown key error with the closest valid name."""
    dotted = _join(prefix, key)
    close = difflib.get_close_matches(key, valid, n=1, cutoff=0.6)
    if close:
        return ConfigError(src, dotted, f"unknown key {dotted!r}; did you mean {close[0]!r}?")
    where = f"in [{prefix}]" if prefix else "at the top level"
    return ConfigError(src, dotted, f"unknown key {dotted!r}; valid keys {where} are {', '.join(valid)}.")


def _build(cls: type, data: Any, prefix: str, src: str, skip: Iterable[str] = ()) -> Any:
    """Build dataclass `cls` from table `data`, rejecting unknown keys and wrong types."""
    if not isinstance(data, dict):
        if prefix.endswith("]"):  # an entry of an array of tables, e.g. material_map[0]
            what, fix = prefix, f"a [[{prefix[: prefix.rindex('[')]}]] table"
        else:
            what, fix = (f"[{prefix}]" if prefix else "the config"), f"a [{prefix}] section"
        raise ConfigError(src, prefix, f"{what} must be a table, not {describe(data)}; write it as {fix}.")
    hints = _hints(cls)
    valid = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in data.items():
        if key in skip:
            continue
        if key not in hints:
            raise _unknown_key(src, prefix, key, valid + list(skip))
        dotted = _join(prefix, key)
        special = _SPECIAL.get((cls, key))
        kwargs[key] = special(value, dotted, src) if special else _convert(value, hints[key], dotted, src, cls, key)
    return cls(**kwargs)


def _array(value: Any, dotted: str, src: str, what: str, example: str) -> list:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(
            src, dotted, f"{dotted} must be an array of {what}, not {describe(value)}; write it like {example}."
        )
    return list(value)


def _build_boundaries(value: Any, dotted: str, src: str) -> list:
    """`[[sim.boundaries]]` tables → PlaneBoundary / CuboidBoundary / SphereBoundary / ParticleRegion."""
    example = '[[sim.boundaries]] tables with type = "plane", "cuboid", "sphere" or "region"'
    items = _array(value, dotted, src, "tables", example)
    out = []
    for i, item in enumerate(items):
        path = f"{dotted}[{i}]"
        if not isinstance(item, dict):
            raise ConfigError(src, path, f"{path} must be a table, not {describe(item)}; write it like {example}.")
        kind = item.get("type")
        if not isinstance(kind, str) or kind not in BOUNDARY_TYPES:  # a list or table is no type (and unhashable)
            out_of = ", ".join(repr(k) for k in BOUNDARY_TYPES)
            close = difflib.get_close_matches(str(kind), list(BOUNDARY_TYPES), n=1)
            fix = (
                f"did you mean type = {close[0]!r}?" if close and kind is not None else f"set type to one of {out_of}."
            )
            got = "has no type" if kind is None else f"has type = {kind!r}"
            raise ConfigError(src, f"{path}.type", f"{path} {got}; {fix}")
        out.append(_build(BOUNDARY_TYPES[kind], item, path, src, skip=("type",)))
    return out


def _build_material_map(value: Any, dotted: str, src: str) -> list:
    """`[[material_map]]` tables → MaterialMapEntry list."""
    items = _array(value, dotted, src, "tables", "[[material_map]] tables with label = 0")
    return [_build(MaterialMapEntry, item, f"{dotted}[{i}]", src) for i, item in enumerate(items)]


def _build_variants(value: Any, dotted: str, src: str) -> list:
    """`variants = [...]` → list of strings (names are checked by `validate`)."""
    items = _array(value, dotted, src, "strings", 'variants = ["baseline", "full"]')
    for i, item in enumerate(items):
        if not isinstance(item, str):
            raise ConfigError(
                src,
                f"{dotted}[{i}]",
                f'{dotted}[{i}] must be a string, not {describe(item)}; write it like variants = ["baseline", "full"].',
            )
    return items


def _build_planes(value: Any, dotted: str, src: str) -> list:
    """`[[topology.planes]]` tables → OraclePlane list."""
    items = _array(value, dotted, src, "tables", "[[topology.planes]] tables with point, normal and latch_time")
    return [_build(OraclePlane, item, f"{dotted}[{i}]", src) for i, item in enumerate(items)]


def _build_regions(value: Any, dotted: str, src: str) -> list:
    """`[[capture.regions]]` tables → MaterialRegion list."""
    items = _array(value, dotted, src, "tables", '[[capture.regions]] tables with lower, upper and material = "wood"')
    return [_build(MaterialRegion, item, f"{dotted}[{i}]", src) for i, item in enumerate(items)]


_SPECIAL = {
    (TopologyConfig, "planes"): _build_planes,
    (CaptureConfig, "regions"): _build_regions,
    (SimConfig, "boundaries"): _build_boundaries,
    (SceneConfig, "material_map"): _build_material_map,
    (SceneConfig, "variants"): _build_variants,
}


def build_scene(data: dict, src: str) -> SceneConfig:
    """Build a SceneConfig (keys and types), reconcile the material model and normalize normals."""
    cfg = _build(SceneConfig, data, "", src)
    _sync_material(cfg, data, src)
    _normalize_normals(cfg)
    return cfg


def _sync_material(cfg: SceneConfig, data: dict, src: str) -> None:
    """`sim.material` and `material.model` are one setting: copy whichever the file set."""
    in_sim = isinstance(data.get("sim"), dict) and "material" in data["sim"]
    in_mat = isinstance(data.get("material"), dict) and "model" in data["material"]
    if in_sim and in_mat and cfg.sim.material != cfg.material.model:
        raise ConfigError(
            src,
            "sim.material",
            f"sim.material = {cfg.sim.material!r} disagrees with material.model = {cfg.material.model!r}; "
            "set only material.model.",
        )
    if in_sim and not in_mat:
        cfg.material.model = cfg.sim.material
    elif in_mat:
        cfg.sim.material = cfg.material.model


def _unit(v: tuple) -> tuple:
    """Normalize a 3-vector (unchanged if zero or already unit, so loading is idempotent)."""
    n = math.sqrt(sum(c * c for c in v))
    if n == 0.0 or abs(n - 1.0) < 1e-12:
        return tuple(v)
    return tuple(c / n for c in v)


def _normalize_normals(cfg: SceneConfig) -> None:
    cfg.topology.normal = _unit(cfg.topology.normal)
    for plane in cfg.topology.planes:
        plane.normal = _unit(plane.normal)
    for b in cfg.sim.boundaries:
        if isinstance(b, PlaneBoundary):
            b.normal = _unit(b.normal)


def set_key(cfg: SceneConfig, dotted: str, value: Any, src: str) -> None:
    """Set one dotted TOML key of `cfg` (e.g. `capture.load`) as the file's reader would: the key must exist and
    the value must have its field's type and choices (a ConfigError naming the key otherwise). The caller
    validates the whole config afterwards, as for a file."""
    *path, key = dotted.split(".")
    target: Any = cfg
    for i, part in enumerate(path):
        valid = [f.name for f in dataclasses.fields(target)]
        if part not in valid or not dataclasses.is_dataclass(getattr(target, part)):
            raise _unknown_key(src, ".".join(path[:i]), part, valid)
        target = getattr(target, part)
    cls = type(target)
    valid = [f.name for f in dataclasses.fields(cls)]
    if key not in valid:
        raise _unknown_key(src, ".".join(path), key, valid)
    setattr(target, key, _convert(value, _hints(cls)[key], dotted, src, cls, key))
