"""Finding config files, reading TOML and resolving `extends` chains: path or name → SceneConfig.

`load_config` is the front door: find the file, read it, apply `extends` recursively (tables
deep-merge key by key; scalars and arrays replace), build the dataclasses (`build.py`) and check
every value (`validate.py`).
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path
from typing import Any, Optional, Union

import tomllib

from ...config import SceneConfig
from ...errors import ArgumentError, ConfigError
from ..detect import is_splat_file
from .build import build_scene, describe
from .dump import to_dict
from .validate import validate

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs"
"""Package data directory holding the built-in TOML configs (repo-root `configs/` links here)."""


def builtin_configs() -> list[str]:
    """Names of the built-in configs (file stems in the package's `configs/` directory)."""
    if not CONFIG_DIR.is_dir():
        return []
    return sorted(p.stem for p in CONFIG_DIR.glob("*.toml"))


def find_config(name_or_path: Union[str, os.PathLike]) -> Path:
    """Resolve a config path, a path without `.toml`, or a bare built-in name like `bread`."""
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ArgumentError(
            f"load_config: path_or_name must be a TOML path or a built-in name (str or pathlib.Path), got "
            f"{type(name_or_path).__name__}; pass e.g. 'bread' or 'configs/my_scene.toml'."
        )
    text = os.fspath(name_or_path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if not text.strip():
        raise ConfigError(
            "", None, "the config name is empty; pass a TOML path, a splat file or a built-in name like bread."
        )
    path = Path(text).expanduser()
    if path.is_file():
        return path
    if path.is_dir():
        raise ConfigError(
            text, None, "is a folder, not a config; pass a TOML file in it or a built-in name like bread."
        )
    if path.suffix != ".toml" and path.name and path.with_name(path.name + ".toml").is_file():
        return path.with_name(path.name + ".toml")
    if len(path.parts) == 1:
        stem = path.stem if path.suffix == ".toml" else path.name
        candidate = CONFIG_DIR / f"{stem}.toml"
        if candidate.is_file():
            return candidate
    if is_splat_file(path):
        kind = "PLY" if path.suffix.lower() == ".ply" else path.suffix.lower()
        raise ConfigError(text, None, f"no such {kind} file; check the path (a {kind} argument is a captured scene).")
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
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(
            src, None, f"cannot read the file ({exc.strerror}); check the path and permissions."
        ) from None
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark (Windows editors) is not part of the TOML
    except UnicodeDecodeError as exc:
        raise ConfigError(
            src, None, f"is not UTF-8 text (byte {raw[exc.start]:#04x} at offset {exc.start}); save it as UTF-8."
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(src, None, f"invalid TOML ({exc}); fix the syntax there.") from None
    except RecursionError:
        raise ConfigError(
            src, None, "nests arrays or tables too deeply for a config; a config needs at most a few levels."
        ) from None


def _resolve_extends(value: Any, base_dir: Optional[Path], src: str) -> Path:
    """Find the file an `extends` key names: relative to the extending file, then built-ins."""
    if not isinstance(value, str) or not value:
        raise ConfigError(
            src, "extends", 'extends must be a config name or path string; write it like extends = "bread".'
        )
    found = None
    if base_dir is not None:
        found = next((c for c in (base_dir / value, base_dir / f"{value}.toml") if c.is_file()), None)
    if found is None:
        try:
            found = find_config(value)
        except ConfigError:
            names = ", ".join(builtin_configs())
            raise ConfigError(
                src,
                "extends",
                f"extends = {value!r} names no config file; use a path relative to this file or a built-in name "
                f"({names}).",
            ) from None
    if is_splat_file(found):  # checked here, wherever it was found: read as TOML it is "not UTF-8 text"
        raise ConfigError(
            src,
            "extends",
            f"extends = {value!r} names a splat file, which is a scene, not a config; write scene = {value!r} "
            'instead (with extends = "capture" for the capture settings).',
        )
    return found


def _deep_merge(base: dict, over: dict) -> dict:
    """Tables merge key by key; any other value in `over` replaces the base's."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def _resolve_chain(
    raw: dict, src: str, base_dir: Optional[Path], seen: tuple[Path, ...]
) -> tuple[dict, Optional[SceneConfig]]:
    """Apply `extends` recursively; each file's own keys are checked under its own name. Returns the merged
    dict and, when there was no `extends`, the config already built from it (so it is not built twice)."""
    raw = dict(raw)
    parent = raw.pop("extends", None)
    own = build_scene(raw, src)  # keys and types of this file alone, so errors name the right file
    if parent is None:
        return raw, own
    base_path = _resolve_extends(parent, base_dir, src)
    if base_path.resolve() in seen:
        raise ConfigError(src, "extends", f"extends = {parent!r} forms a cycle; remove one of the extends keys.")
    base_raw = _read_toml(base_path)
    base, _ = _resolve_chain(base_raw, _display(base_path), base_path.parent, seen + (base_path.resolve(),))
    return _deep_merge(base, raw), None


def load_config(path_or_name: Union[str, os.PathLike]) -> SceneConfig:
    """Load, resolve `extends`, type-check, normalize and validate a TOML config. A splat file (a 3DGS or
    compressed .ply, .splat, .spz, recognised by suffix or content: `formats.is_splat_file`) is a captured
    scene with automatic settings: the built-in `capture` config with `scene` = that file."""
    path = find_config(path_or_name)
    if is_splat_file(path):
        return ply_config(path)
    src = _display(path)
    raw = _read_toml(path)
    if "accuracy" in raw or "sweep" in raw or isinstance(raw.get("scene"), list):
        raise ConfigError(
            src,
            None,
            "is a sweep spec ([[accuracy]] or [[scene]] tables), not a scene config; run it with "
            f"`fracture-gs sweep {path}` (or `fracture-gs sweep {path} --list` to see its cells).",
        )
    merged, cfg = _resolve_chain(raw, src, path.parent, (path.resolve(),))
    cfg = cfg or build_scene(merged, src)
    validate(cfg, src)
    return cfg


def ply_config(path: Path) -> SceneConfig:
    """The config of a bare splat-file argument: `extends = "capture"`, the scene, a name from the file."""
    stem = path.name[: -len(".compressed.ply")] if path.name.lower().endswith(".compressed.ply") else path.stem
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("._") or "scene"
    if name == "point_cloud" and path.parent.name.startswith("iteration_"):  # the reference trainer's layout
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", path.parent.parent.parent.name) or name
    return config_from_dict({"extends": "capture", "scene": str(path.resolve()), "name": name}, _display(path))


def config_from_dict(d: dict, source: str = "<dict>") -> SceneConfig:
    """Build a SceneConfig from a plain dict shaped like the TOML (same checks as `load_config`).

    An `extends` key resolves relative to the working directory, then to the built-in configs."""
    if not isinstance(d, dict):
        raise ConfigError(source, None, f"a config must be a table (dict), not {describe(d)}; pass a dict of sections.")
    merged, cfg = _resolve_chain(_plain(d, source), source, Path.cwd(), ())
    cfg = cfg or build_scene(merged, source)
    validate(cfg, source)
    return cfg


def _plain(value: Any, source: str, where: str = "") -> Any:
    """Turn dataclass instances inside a user dict into TOML-shaped dicts (boundaries get `type`), and numpy
    numbers and arrays into Python ones (np.int64(3) is the integer 3, as TOML would have read it). A key that is
    not a string (no TOML table has one) is a ConfigError naming it."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_dict(value)
    if isinstance(value, dict):
        bad = next((k for k in value if not isinstance(k, str)), None)
        if bad is not None:
            raise ConfigError(
                source,
                None,
                f"key {bad!r:.40} {f'in [{where}] ' if where else ''}has type {type(bad).__name__}, not str; "
                "write every key as a string, e.g. {'frames': 30}.",
            )
        return {k: _plain(v, source, f"{where}.{k}" if where else k) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v, source, where) for v in value)
    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):  # np.int64, np.float32, np.ndarray
        return _plain(value.tolist(), source, where)
    return value
