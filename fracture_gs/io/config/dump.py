"""Writing a SceneConfig as TOML that `load_config` reads back to an equal SceneConfig."""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, Optional

from ...config import BOUNDARY_TYPES, BUILTIN_SCENES, SceneConfig
from ..detect import is_splat_file


def to_plain_value(value: Any) -> Any:
    """Tuples → lists, dataclasses → dicts; recursively."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_dict(value)
    if isinstance(value, (list, tuple)):
        return [to_plain_value(v) for v in value]
    return value


def to_dict(obj: Any) -> dict:
    """One dataclass → TOML-shaped dict; None fields are left out, boundaries get `type` first."""
    out: dict[str, Any] = {}
    for kind, cls in BOUNDARY_TYPES.items():
        if type(obj) is cls:
            out["type"] = kind
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is not None:
            out[f.name] = to_plain_value(value)
    return out


def config_to_dict(cfg: SceneConfig) -> dict:
    """SceneConfig → plain dict shaped like the TOML (inverse of `config_from_dict`). The [capture]
    table is left out while it holds only defaults and the scene is not a splat file (it would say nothing)."""
    out = to_dict(cfg)
    if cfg.capture == type(cfg.capture)() and (cfg.scene in BUILTIN_SCENES or not is_splat_file(cfg.scene)):
        out.pop("capture", None)
    return out


def toml_value(value: Any) -> str:
    """One TOML value (scalars and inline arrays)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as a TOML value")


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _emit(lines: list[str], path: str, table: dict) -> None:
    """Write a table's scalars, then its sub-tables and arrays of tables."""
    for key, value in table.items():
        if not isinstance(value, dict) and not _is_table_array(value):
            lines.append(f"{key} = {toml_value(value)}")
    for key, value in table.items():
        sub = _join(path, key)
        if isinstance(value, dict):
            lines += ["", f"[{sub}]"]
            _emit(lines, sub, value)
        elif _is_table_array(value):
            for item in value:
                lines += ["", f"[[{sub}]]"]
                _emit(lines, sub, item)


def dump_config(cfg: SceneConfig, header: Optional[str] = None) -> str:
    """SceneConfig → TOML text that `load_config` reads back to an equal SceneConfig."""
    if not isinstance(cfg, SceneConfig):
        from ...errors import ArgumentError

        raise ArgumentError(
            f"dump_config: cfg must be a SceneConfig, got {type(cfg).__name__}; load one with "
            "fracture_gs.io.load_config('bread') (or a path)."
        )
    if header is not None and not isinstance(header, str):
        from ...errors import ArgumentError

        raise ArgumentError(
            f"dump_config: header must be a string (or None), got {type(header).__name__}; pass e.g. header='my scene'."
        )
    return dump_dict(config_to_dict(cfg), header)


def dump_dict(plain: dict, header: Optional[str] = None) -> str:
    """`config_to_dict`'s dict → the TOML text `dump_config` writes (for a caller that holds the dict already)."""
    lines: list[str] = [f"# {line}" for line in (header or "").splitlines()]
    _emit(lines, "", plain)
    return "\n".join(lines).lstrip("\n") + "\n"
