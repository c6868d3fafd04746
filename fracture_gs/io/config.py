"""Scene configs: TOML files ⇄ the dataclasses of `fracture_gs.config`.

File layout (every key is a field of `fracture_gs.config`; all are optional, defaults fill in)::

    extends = "bread"          # optional: start from another config, then apply this file
    name = "bread"             # SceneConfig scalars at the top level
    frames = 90
    variants = ["baseline", "full"]

    [sim]                      # SimConfig
    dt = 2e-4
    gravity = [0.0, 0.0, -9.8]
    [[sim.boundaries]]         # one table per boundary; `type` picks the class:
    type = "plane"             #   "plane" → PlaneBoundary, "cuboid" → CuboidBoundary,
    point = [0.0, 0.0, 0.1]    #   "region" → ParticleRegion
    [material]                 # MaterialConfig (the default material)
    [[material_map]]           # MaterialMapEntry per label (unset fields keep the default)
    [topology]                 # TopologyConfig
    [render]                   # RenderConfig
    [render.camera]            # CameraConfig

Rules:
  * Loading is strict. An unknown key, a value of the wrong type or an invalid value raises
    `ConfigError` (a `ValueError`) with one sentence naming the file, the dotted field and the fix.
  * `extends` names a built-in config (`"bread"`) or a path relative to the extending file. The
    base is loaded first (recursively); tables are deep-merged key by key, while scalars and arrays
    (including arrays of tables such as `sim.boundaries`, `material_map`, `variants`) replace the
    base's value as a whole.
  * `material.model` and `sim.material` name the same thing; set either one and the other follows.
  * Normals (`PlaneBoundary.normal`, `topology.normal`) are normalized on load.
  * Presets: `preset` is `small` (Δx = 1/64) or `paper` (Δx = 1/128). A file is taken literally;
    `apply_overrides(cfg, preset=...)` (the CLI's `--preset`) switches an existing config to the
    preset's Δx, rescales the explicit grid shape to cover the same box (64³ ↔ 128³) and rescales
    `sim.dt` by the same ratio so the CFL number stays put. It is idempotent.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import json
import math
import os
import tomllib
import typing
from pathlib import Path
from typing import Any, Iterable, Optional, Sequence, Union

from ..errors import ConfigError
from ..config import (
    MATERIALS,
    PLANE_MODES,
    VARIANTS,
    CuboidBoundary,
    MaterialMapEntry,
    ParticleRegion,
    PlaneBoundary,
    RenderConfig,
    SceneConfig,
    SimConfig,
    TopologyConfig,
)

__all__ = [
    "ConfigError",
    "load_config",
    "config_from_dict",
    "config_to_dict",
    "dump_config",
    "builtin_configs",
    "find_config",
    "apply_overrides",
    "validate",
    "parse_resolution",
    "parse_variants",
    "CONFIG_DIR",
    "BOUNDARY_TYPES",
    "PRESETS",
    "PROVIDERS",
    "BUILTIN_SCENES",
]

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"
"""Package data directory holding the built-in TOML configs (repo-root `configs/` links here)."""

BOUNDARY_TYPES: dict[str, type] = {"plane": PlaneBoundary, "cuboid": CuboidBoundary, "region": ParticleRegion}
"""Value of a `[[sim.boundaries]]` table's `type` key → boundary class."""

PRESETS: dict[str, float] = {"small": 1.0 / 64, "paper": 1.0 / 128}
"""Preset name → grid spacing Δx it selects (see `apply_overrides`)."""

PROVIDERS = ("none", "oracle", "stress")
BUILTIN_SCENES = ("bread", "ficus", "recontact", "beam", "plane_drop")
REGION_KINDS = ("impulse", "velocity")
GRID_KINDS = ("explicit", "auto")
RENDER_MODES = ("classic", "antialiased")
RENDER_BACKENDS = ("auto", "gsplat", "torch")
NEEDS_PROVIDER = tuple(v for v in VARIANTS if v != "baseline")




# --------------------------------------------------------------------------------------------
# finding and reading files


def builtin_configs() -> list[str]:
    """Names of the built-in configs (file stems in the package's `configs/` directory)."""
    if not CONFIG_DIR.is_dir():
        return []
    return sorted(p.stem for p in CONFIG_DIR.glob("*.toml"))


def find_config(name_or_path: Union[str, os.PathLike]) -> Path:
    """Resolve a config path, a path without `.toml`, or a bare built-in name like `bread`."""
    text = os.fspath(name_or_path)
    path = Path(text).expanduser()
    if path.is_file():
        return path
    if path.suffix != ".toml" and path.with_name(path.name + ".toml").is_file():
        return path.with_name(path.name + ".toml")
    if len(path.parts) == 1:
        stem = path.stem if path.suffix == ".toml" else path.name
        candidate = CONFIG_DIR / f"{stem}.toml"
        if candidate.is_file():
            return candidate
    if path.suffix.lower() == ".ply":
        raise ConfigError(text, None, f"this is a 3DGS scene, not a config; write a TOML config with scene = \"{text}\" (for instance extends = \"bread\" plus that line) and pass the TOML instead.")
    names = ", ".join(builtin_configs()) or "none installed"
    raise ConfigError(text, None, f"no such config file; pass a path to a TOML file or a built-in name ({names}).")


def _display(path: Path) -> str:
    """Short form of a path for messages: relative to the working directory when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _read_toml(path: Path) -> dict:
    """Parse one TOML file, turning syntax errors into ConfigError."""
    src = _display(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(src, None, f"invalid TOML ({exc}); fix the syntax there.") from None
    except OSError as exc:
        raise ConfigError(src, None, f"cannot read the file ({exc.strerror}); check the path and permissions.") from None


def _resolve_extends(value: Any, base_dir: Optional[Path], src: str) -> Path:
    """Find the file an `extends` key names: relative to the extending file, then built-ins."""
    if not isinstance(value, str) or not value:
        raise ConfigError(src, "extends", "extends must be a config name or path string; write it like extends = \"bread\".")
    if base_dir is not None:
        for candidate in (base_dir / value, base_dir / f"{value}.toml"):
            if candidate.is_file():
                return candidate
    try:
        return find_config(value)
    except ConfigError:
        names = ", ".join(builtin_configs())
        raise ConfigError(src, "extends", f"extends = {value!r} names no config file; use a path relative to this file or a built-in name ({names}).") from None


def _deep_merge(base: dict, over: dict) -> dict:
    """Tables merge key by key; any other value in `over` replaces the base's."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def _resolve_chain(raw: dict, src: str, base_dir: Optional[Path], seen: tuple[Path, ...]) -> dict:
    """Apply `extends` recursively; each file's own keys are checked under its own name."""
    raw = dict(raw)
    parent = raw.pop("extends", None)
    _build_scene(raw, src)  # keys and types of this file alone, so errors name the right file
    if parent is None:
        return raw
    base_path = _resolve_extends(parent, base_dir, src)
    if base_path.resolve() in seen:
        raise ConfigError(src, "extends", f"extends = {parent!r} forms a cycle; remove one of the extends keys.")
    base_raw = _read_toml(base_path)
    base = _resolve_chain(base_raw, _display(base_path), base_path.parent, seen + (base_path.resolve(),))
    return _deep_merge(base, raw)


def load_config(path_or_name: Union[str, os.PathLike]) -> SceneConfig:
    """Load, resolve `extends`, type-check, normalize and validate a TOML config."""
    path = find_config(path_or_name)
    src = _display(path)
    merged = _resolve_chain(_read_toml(path), src, path.parent, (path.resolve(),))
    cfg = _build_scene(merged, src)
    validate(cfg, src)
    return cfg


def config_from_dict(d: dict, source: str = "<dict>") -> SceneConfig:
    """Build a SceneConfig from a plain dict shaped like the TOML (same checks as `load_config`).

    An `extends` key resolves relative to the working directory, then to the built-in configs."""
    if not isinstance(d, dict):
        raise ConfigError(source, None, f"a config must be a table (dict), not {_describe(d)}; pass a dict of sections.")
    merged = _resolve_chain(_plain(d), source, Path.cwd(), ())
    cfg = _build_scene(merged, source)
    validate(cfg, source)
    return cfg


def _plain(value: Any) -> Any:
    """Turn dataclass instances inside a user dict into TOML-shaped dicts (boundaries get `type`)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _to_dict(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    return value


# --------------------------------------------------------------------------------------------
# building dataclasses from dicts (keys and types)


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _describe(value: Any) -> str:
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
    return f"; write it like {key} = {_toml_value(_to_plain_value(default))}"


def _type_error(src: str, dotted: str, tp: Any, value: Any, cls: type, key: str) -> ConfigError:
    hint = _example(cls, key)
    if isinstance(value, str) and typing.get_origin(tp) is not tuple and tp in (float, int):
        hint = f"; write the number without quotes, e.g. {key} = {value.strip()}" if _is_number_text(value) else hint
    return ConfigError(src, dotted, f"{dotted} must be {_type_name(tp)}, not {_describe(value)}{hint or ''}.")


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
    if dataclasses.is_dataclass(tp):
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
        what = f"[{prefix}]" if prefix else "the config"
        raise ConfigError(src, prefix, f"{what} must be a table, not {_describe(data)}; write it as a [{prefix}] section.")
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
        raise ConfigError(src, dotted, f"{dotted} must be an array of {what}, not {_describe(value)}; write it like {example}.")
    return list(value)


def _build_boundaries(value: Any, dotted: str, src: str) -> list:
    """`[[sim.boundaries]]` tables → PlaneBoundary / CuboidBoundary / ParticleRegion."""
    example = '[[sim.boundaries]] tables with type = "plane", "cuboid" or "region"'
    items = _array(value, dotted, src, "tables", example)
    out = []
    for i, item in enumerate(items):
        path = f"{dotted}[{i}]"
        if not isinstance(item, dict):
            raise ConfigError(src, path, f"{path} must be a table, not {_describe(item)}; write it like {example}.")
        kind = item.get("type")
        if kind not in BOUNDARY_TYPES:
            out_of = ", ".join(repr(k) for k in BOUNDARY_TYPES)
            close = difflib.get_close_matches(str(kind), list(BOUNDARY_TYPES), n=1)
            fix = f"did you mean type = {close[0]!r}?" if close and kind is not None else f"set type to one of {out_of}."
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
            raise ConfigError(src, f"{dotted}[{i}]", f"{dotted}[{i}] must be a string, not {_describe(item)}; write it like variants = [\"baseline\", \"full\"].")
    return items


_SPECIAL = {
    (SimConfig, "boundaries"): _build_boundaries,
    (SceneConfig, "material_map"): _build_material_map,
    (SceneConfig, "variants"): _build_variants,
}


def _build_scene(data: dict, src: str) -> SceneConfig:
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
        raise ConfigError(src, "sim.material", f"sim.material = {cfg.sim.material!r} disagrees with material.model = {cfg.material.model!r}; set only material.model.")
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
    for b in cfg.sim.boundaries:
        if isinstance(b, PlaneBoundary):
            b.normal = _unit(b.normal)


# --------------------------------------------------------------------------------------------
# validation (values)


class _Checker:
    """Collects nothing: raises on the first problem, naming source and field."""

    def __init__(self, source: str):
        self.src = source

    def fail(self, field: str, problem: str, fix: str) -> None:
        raise ConfigError(self.src, field, f"{problem}; {fix}.")

    def choice(self, field: str, value: Any, options: Sequence[str]) -> None:
        if value in options:
            return
        close = difflib.get_close_matches(str(value), list(options), n=1)
        fix = f"did you mean {close[0]!r}?" if close else "use one of them."
        raise ConfigError(self.src, field, f"{field} = {value!r} is not one of {', '.join(options)}; {fix}")

    def positive(self, field: str, value: float, fix: str) -> None:
        if not (value > 0 and math.isfinite(value)):
            self.fail(field, f"{field} = {value!r} must be a positive finite number", fix)

    def at_least(self, field: str, value: float, low: float, fix: str) -> None:
        if not value >= low:
            self.fail(field, f"{field} = {value!r} must be at least {low}", fix)

    def within(self, field: str, value: float, low: float, high: float, fix: str, open_high: bool = False) -> None:
        ok = low <= value < high if open_high else low <= value <= high
        if not ok:
            bracket = ")" if open_high else "]"
            self.fail(field, f"{field} = {value!r} is outside [{low}, {high}{bracket}", fix)

    def nonzero(self, field: str, v: tuple, fix: str) -> None:
        if not any(c != 0 for c in v) or not all(math.isfinite(c) for c in v):
            self.fail(field, f"{field} = {list(v)} must be a finite nonzero vector", fix)

    def box(self, prefix: str, lower: tuple, upper: tuple) -> None:
        if not all(lo < hi for lo, hi in zip(lower, upper)):
            self.fail(f"{prefix}.lower", f"{prefix}.lower {list(lower)} is not below {prefix}.upper {list(upper)} on every axis", "swap or fix the corners so lower < upper")

    def interval(self, prefix: str, start: float, end: float) -> None:
        if not (0 <= start <= end):
            self.fail(f"{prefix}.start", f"{prefix}.start = {start!r} and end = {end!r} do not form a time interval", "use 0 <= start <= end (seconds)")


def validate(cfg: SceneConfig, source: str = "<config>") -> SceneConfig:
    """Check every value of a SceneConfig; raise ConfigError (one sentence) on the first problem."""
    c = _Checker(source)
    _check_scene(c, cfg)
    _check_material(c, "material", cfg.material)
    _check_sim(c, cfg.sim, cfg.frame_dt)
    _check_material_map(c, cfg.material_map)
    _check_topology(c, cfg.topology, cfg.frames)
    _check_render(c, cfg.render)
    _check_provider_needed(c, cfg)
    return cfg


def _check_scene(c: _Checker, cfg: SceneConfig) -> None:
    if not cfg.name or any(ch in cfg.name for ch in "/\\:") or cfg.name.strip() != cfg.name:
        c.fail("name", f"name = {cfg.name!r} cannot be used as a folder name", "use letters, digits, '_', '-' or '.'")
    if cfg.scene not in BUILTIN_SCENES and not cfg.scene.lower().endswith(".ply"):
        c.fail("scene", f"scene = {cfg.scene!r} is neither a built-in scene nor a .ply path", f"use one of {', '.join(BUILTIN_SCENES)} or a path ending in .ply")
    c.choice("preset", cfg.preset, list(PRESETS))
    c.at_least("frames", cfg.frames, 1, "simulate at least one frame")
    c.positive("frame_dt", cfg.frame_dt, "give the time between frames in seconds, e.g. frame_dt = 0.01")
    if cfg.material_property is not None and not cfg.material_property:
        c.fail("material_property", "material_property is empty", "name the PLY property holding the labels or remove the key")
    _check_variants(c, cfg)


def _check_variants(c: _Checker, cfg: SceneConfig) -> None:
    if not cfg.variants:
        c.fail("variants", "variants is empty", f"list at least one of {', '.join(VARIANTS)}")
    for i, v in enumerate(cfg.variants):
        c.choice(f"variants[{i}]", v, VARIANTS)
    if len(set(cfg.variants)) != len(cfg.variants):
        c.fail("variants", f"variants {cfg.variants} lists a variant twice", "list each variant once")


def _check_provider_needed(c: _Checker, cfg: SceneConfig) -> None:
    """Every variant but baseline needs fragment labels, hence an event provider."""
    needing = [v for v in cfg.variants if v in NEEDS_PROVIDER]
    if needing and cfg.topology.provider == "none":
        c.fail("topology.provider", f"variants {needing} need a fracture event provider but topology.provider = 'none'", "set topology.provider = \"stress\" or \"oracle\", or run only baseline")


def _check_sim(c: _Checker, s: SimConfig, frame_dt: float) -> None:
    c.positive("sim.dt", s.dt, "give the substep in seconds, e.g. dt = 1e-4")
    if s.dt > frame_dt:
        c.fail("sim.dt", f"sim.dt = {s.dt!r} is longer than frame_dt = {frame_dt!r}", "use a substep no longer than one frame")
    if not s.adaptive_dt and frame_dt / s.dt > s.max_substeps_per_frame * (1 + 1e-9):
        c.fail("sim.max_substeps_per_frame", f"frame_dt / sim.dt = {frame_dt / s.dt:.0f} substeps exceeds sim.max_substeps_per_frame = {s.max_substeps_per_frame}", "raise max_substeps_per_frame or sim.dt")
    c.within("sim.cfl", s.cfl, 1e-12, 1.0, "use a CFL number in (0, 1], e.g. cfl = 0.4")
    c.choice("sim.variant", s.variant, VARIANTS)
    c.choice("sim.grid", s.grid, GRID_KINDS)
    c.positive("sim.dx", s.dx, "give the grid spacing in metres, e.g. dx = 0.015625")
    c.at_least("sim.wall_cells", s.wall_cells, 0, "use 0 or more cells")
    for i, n in enumerate(s.grid_shape):
        if n < max(4, 2 * s.wall_cells + 2):
            c.fail(f"sim.grid_shape[{i}]", f"sim.grid_shape[{i}] = {n} is too small for the B-spline stencil and {s.wall_cells} wall cells", f"use at least {max(4, 2 * s.wall_cells + 2)} nodes per axis")
    c.at_least("sim.grid_margin", s.grid_margin, 0.0, "use a non-negative fraction, e.g. grid_margin = 0.5")
    if s.grid_bounds is not None:
        c.box("sim.grid_bounds", s.grid_bounds[0], s.grid_bounds[1])
    if not all(math.isfinite(g) for g in s.gravity):
        c.fail("sim.gravity", f"sim.gravity = {list(s.gravity)} is not finite", "give three finite numbers in m/s², e.g. [0, 0, -9.8]")
    c.choice("sim.material", s.material, MATERIALS)
    c.within("sim.restitution", s.restitution, 0.0, 1.0, "use a restitution in [0, 1]")
    c.at_least("sim.eps_mass", s.eps_mass, 0.0, "use a non-negative threshold, e.g. eps_mass = 1e-3")
    c.at_least("sim.eps_band", s.eps_band, 0.0, "use a non-negative threshold, e.g. eps_band = 1e-3")
    c.at_least("sim.max_substeps_per_frame", s.max_substeps_per_frame, 1, "use a positive bound")
    for i, b in enumerate(s.boundaries):
        _check_boundary(c, f"sim.boundaries[{i}]", b)


def _check_boundary(c: _Checker, p: str, b: Any) -> None:
    if isinstance(b, PlaneBoundary):
        c.choice(f"{p}.mode", b.mode, PLANE_MODES)
        c.nonzero(f"{p}.normal", b.normal, "give the outward normal, e.g. normal = [0, 0, 1]")
        c.at_least(f"{p}.friction", b.friction, 0.0, "use a non-negative Coulomb coefficient")
    elif isinstance(b, CuboidBoundary):
        c.box(p, b.lower, b.upper)
        c.interval(p, b.start, b.end)
    elif isinstance(b, ParticleRegion):
        c.choice(f"{p}.kind", b.kind, REGION_KINDS)
        c.box(p, b.lower, b.upper)
        c.interval(p, b.start, b.end)
    else:
        c.fail(p, f"{p} is a {type(b).__name__}, not a boundary", "use PlaneBoundary, CuboidBoundary or ParticleRegion")


def _check_material(c: _Checker, p: str, m: Any) -> None:
    """Shared by the default material and material-map entries (None = keep default)."""
    if m.model is not None:
        c.choice(f"{p}.model", m.model, MATERIALS)
    if m.E is not None:
        c.positive(f"{p}.E", m.E, "give Young's modulus in pascals, e.g. E = 2e6")
    if m.nu is not None:
        c.within(f"{p}.nu", m.nu, 0.0, 0.5, "use a Poisson ratio below 0.5, e.g. nu = 0.3", open_high=True)
    if m.density is not None:
        c.positive(f"{p}.density", m.density, "give the density in kg/m³, e.g. density = 200")
    if m.yield_stress is not None:
        c.positive(f"{p}.yield_stress", m.yield_stress, "give the yield stress in pascals")
    if m.hardening is not None:
        c.at_least(f"{p}.hardening", m.hardening, 0.0, "use a non-negative hardening coefficient")
    if m.friction_angle is not None:
        c.within(f"{p}.friction_angle", m.friction_angle, 0.0, 90.0, "use an angle in degrees below 90", open_high=True)
    if m.sigma_R is not None:
        c.positive(f"{p}.sigma_R", m.sigma_R, "give the fracture strength in pascals, e.g. sigma_R = 5e4")


def _check_material_map(c: _Checker, entries: list) -> None:
    seen: set[int] = set()
    for i, e in enumerate(entries):
        p = f"material_map[{i}]"
        if not isinstance(e, MaterialMapEntry):
            c.fail(p, f"{p} is a {type(e).__name__}, not a MaterialMapEntry", "use [[material_map]] tables")
        c.at_least(f"{p}.label", e.label, 0, "use a non-negative integer label")
        if e.label in seen:
            c.fail(f"{p}.label", f"{p}.label = {e.label} appears twice in material_map", "give each label one entry")
        seen.add(e.label)
        _check_material(c, p, e)


def _check_topology(c: _Checker, t: TopologyConfig, frames: int) -> None:
    c.choice("topology.provider", t.provider, PROVIDERS)
    c.nonzero("topology.normal", t.normal, "give the plane normal, e.g. normal = [1, 0, 0]")
    c.at_least("topology.latch_frame", t.latch_frame, 0, "use a frame index >= 0")
    if t.latch_frame > frames:
        c.fail("topology.latch_frame", f"topology.latch_frame = {t.latch_frame} is after the last frame ({frames})", "latch within the run or raise frames")
    if t.latch_time is not None:
        c.at_least("topology.latch_time", t.latch_time, 0.0, "use a time in seconds >= 0")
    c.at_least("topology.min_particles", t.min_particles, 1, "need at least one over-stressed particle")
    c.at_least("topology.persist_frames", t.persist_frames, 1, "use at least one frame")
    c.positive("topology.band_width", t.band_width, "give the band half-width in Δx, e.g. band_width = 1.0")
    c.positive("topology.pair_radius", t.pair_radius, "give the pair radius in Δx, e.g. pair_radius = 1.5")
    c.within("topology.direction_agreement", t.direction_agreement, 0.0, 1.0, "use a |cos| threshold in [0, 1]")


def _check_render(c: _Checker, r: RenderConfig) -> None:
    c.at_least("render.width", r.width, 2, "use an image width of at least 2 pixels")
    c.at_least("render.height", r.height, 2, "use an image height of at least 2 pixels")
    c.at_least("render.fps", r.fps, 1, "use a positive frame rate")
    c.choice("render.mode", r.mode, RENDER_MODES)
    c.choice("render.backend", r.backend, RENDER_BACKENDS)
    for i, ch in enumerate(r.background):
        c.within(f"render.background[{i}]", ch, 0.0, 1.0, "give RGB components in [0, 1]")
    c.at_least("render.inset_radius", r.inset_radius, 0, "use a radius in pixels >= 0")
    c.positive("render.inset_zoom", r.inset_zoom, "use a magnification > 0, e.g. inset_zoom = 2.5")
    cam = r.camera
    c.within("render.camera.fov_deg", cam.fov_deg, 1e-6, 179.0, "use a field of view in degrees between 0 and 179")
    c.nonzero("render.camera.up", cam.up, "give an up vector, e.g. up = [0, 0, 1]")
    view = tuple(t - e for t, e in zip(cam.target, cam.eye))
    c.nonzero("render.camera.target", view, "put the camera eye and target at different points")
    cross = (view[1] * cam.up[2] - view[2] * cam.up[1], view[2] * cam.up[0] - view[0] * cam.up[2], view[0] * cam.up[1] - view[1] * cam.up[0])
    if math.sqrt(sum(x * x for x in cross)) <= 1e-9 * math.sqrt(sum(x * x for x in view)) * math.sqrt(sum(x * x for x in cam.up)):
        c.fail("render.camera.up", f"render.camera.up = {list(cam.up)} is parallel to the viewing direction", "tilt the eye or choose another up vector")


# --------------------------------------------------------------------------------------------
# writing


def _to_plain_value(value: Any) -> Any:
    """Tuples → lists, dataclasses → dicts; recursively."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _to_dict(value)
    if isinstance(value, (list, tuple)):
        return [_to_plain_value(v) for v in value]
    return value


def _to_dict(obj: Any) -> dict:
    """One dataclass → TOML-shaped dict; None fields are left out, boundaries get `type` first."""
    out: dict[str, Any] = {}
    for kind, cls in BOUNDARY_TYPES.items():
        if type(obj) is cls:
            out["type"] = kind
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is not None:
            out[f.name] = _to_plain_value(value)
    return out


def config_to_dict(cfg: SceneConfig) -> dict:
    """SceneConfig → plain dict shaped like the TOML (inverse of `config_from_dict`)."""
    return _to_dict(cfg)


def _toml_value(value: Any) -> str:
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
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as a TOML value")


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _emit(lines: list[str], path: str, table: dict) -> None:
    """Write a table's scalars, then its sub-tables and arrays of tables."""
    for key, value in table.items():
        if not isinstance(value, dict) and not _is_table_array(value):
            lines.append(f"{key} = {_toml_value(value)}")
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
    lines: list[str] = [f"# {line}" for line in (header or "").splitlines()]
    _emit(lines, "", config_to_dict(cfg))
    return "\n".join(lines).lstrip("\n") + "\n"


# --------------------------------------------------------------------------------------------
# command-line overrides


def parse_resolution(text: Union[str, Sequence[int]], source: str = "") -> tuple[int, int]:
    """`"640x480"` (or a (w, h) pair) → (640, 480); both at least 2 pixels."""
    if isinstance(text, str):
        parts = text.lower().replace("×", "x").split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise ConfigError(source, "--resolution", f"--resolution {text!r} is not WIDTHxHEIGHT; write it like --resolution 640x480.")
        w, h = (int(p) for p in parts)
    else:
        w, h = (int(v) for v in text)
    if w < 2 or h < 2:
        raise ConfigError(source, "--resolution", f"--resolution {w}x{h} is too small; use at least 2x2 pixels.")
    return w, h


def parse_variants(text: Union[str, Sequence[str]], source: str = "") -> list[str]:
    """`"baseline,full"` (or a list) → ['baseline', 'full'], each a known variant, no repeats."""
    names = [v.strip() for v in text.split(",")] if isinstance(text, str) else [str(v).strip() for v in text]
    names = [v for v in names if v]
    if not names:
        raise ConfigError(source, "--variants", f"--variants is empty; list some of {', '.join(VARIANTS)}.")
    for v in names:
        if v not in VARIANTS:
            close = difflib.get_close_matches(v, VARIANTS, n=1)
            fix = f"did you mean {close[0]!r}?" if close else f"use names from {', '.join(VARIANTS)}."
            raise ConfigError(source, "--variants", f"--variants names unknown variant {v!r}; {fix}")
    if len(set(names)) != len(names):
        raise ConfigError(source, "--variants", f"--variants {','.join(names)} lists a variant twice; list each once.")
    return names


def _apply_preset(cfg: SceneConfig, preset: str, source: str) -> None:
    """Switch to the preset's Δx; rescale an explicit grid's shape and dt by the Δx ratio."""
    if preset not in PRESETS:
        raise ConfigError(source, "--preset", f"--preset {preset!r} is unknown; use one of {', '.join(PRESETS)}.")
    new_dx = PRESETS[preset]
    ratio = new_dx / cfg.sim.dx
    cfg.preset = preset
    if abs(ratio - 1.0) < 1e-12:
        return
    if cfg.sim.grid == "explicit":
        cfg.sim.grid_shape = tuple(max(4, int(round(n / ratio))) for n in cfg.sim.grid_shape)
    cfg.sim.dx = new_dx
    cfg.sim.dt = cfg.sim.dt * ratio


def apply_overrides(
    cfg: SceneConfig,
    preset: Optional[str] = None,
    frames: Optional[int] = None,
    resolution: Union[str, Sequence[int], None] = None,
    variants: Union[str, Sequence[str], None] = None,
    source: str = "command line",
) -> SceneConfig:
    """Return a validated copy of `cfg` with CLI overrides applied (None = keep).

    `preset="paper"` sets Δx = 1/128 (`"small"`: 1/64), rescales an explicit `grid_shape` to cover
    the same box (64³ → 128³) and `sim.dt` by the same ratio; `resolution` is `"WxH"` or (w, h);
    `variants` is `"a,b"` or a list. A bad flag raises ConfigError naming the flag; the result is
    validated again, naming `source` (e.g. "configs/bread.toml with command-line overrides")."""
    out = copy.deepcopy(cfg)
    if preset is not None:
        _apply_preset(out, preset, "")
    if frames is not None:
        if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
            raise ConfigError("", "--frames", f"--frames {frames!r} must be a positive integer; write it like --frames 30.")
        out.frames = frames
    if resolution is not None:
        out.render.width, out.render.height = parse_resolution(resolution)
    if variants is not None:
        out.variants = parse_variants(variants)
    return validate(out, source)
