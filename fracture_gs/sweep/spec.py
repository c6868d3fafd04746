"""A sweep spec (TOML) → a typed, checked `SweepSpec` (what to run; `expand` makes the cells).

File layout (every key but `config`, `case`, `cells` and `cfl` of an accuracy table is optional)::

    [sweep]
    title = "Speed against error"   # heading of sweep.md
    warmup = true                   # each rank compiles/loads the kernels before its first timed cell
    max_cells = 10000               # refuse a spec whose tables multiply out to more cells (--max-cells)

    [[accuracy]]                    # case × cells × cfl, fracture_gs.paper.accuracy's cases
    label = "dx"                    # the sweep's name in tables and the Pareto plot (dx: circles)
    case = ["bar", "spin"]          # bar, spin, recontact
    cells = [16, 24, 32]            # grid cells per metre: Δx = 1/cells
    cfl = 0.4                       # Δt = cfl·Δx / (wave speed + largest initial speed)

    [[scene]]                       # config × variant × cells × (dt | cfl) × material × seed
    config = ["recontact"]          # built-in names or TOML/PLY paths (relative to this file)
    variant = ["local_multifield", "full"]   # default: the config's own `variants`
    cells = [32, 64]                # grid cells across the config's explicit grid box (a PLY: capture.cells_across)
    dt = [1e-4]                     # fixed substeps [s] ...
    cfl = [0.4]                     # ... and/or adaptive substeps at these CFL numbers
    seed = [0, 1]                   # asset sampling seed and topology.seed
    frames = 10                     # override the config's frame count
    particles = 2000                # built-in scenes: particle count
    preset = "small"                # small | paper
    render = false                  # true: render-sim's videos too (per cell, under OUT/cells/<id>/)
    [scene.material]                # material overrides, each a list: E, nu, density, sigma_R, ...
    E = [1e5, 2e5]
    [scene.set]                     # any other config field by its dotted TOML path
    "sim.contact.friction" = [0.0, 0.3]
    "material_map.0.E" = [4000.0]   # array entries by index

A scalar is a one-element list. `fracture_gs.sweep.expansion.expand` turns a SweepSpec into its cells (cross
products, merged duplicates, stable ids, resolved scene configs).

Every problem is a `ConfigError` with one sentence naming the spec file, the key, the value and
the fix.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

import tomllib

from ..config import PRESETS, MaterialConfig
from ..errors import ConfigError
from ..io.config import CONFIG_DIR
from ..io.detect import is_splat_file
from ..variants import VARIANT_NAMES

SPEC_DIR = CONFIG_DIR / "sweeps"
"""Built-in sweep specs (`fracture-gs sweep accuracy` finds `SPEC_DIR/accuracy.toml`). They sit in a
sub-folder so that the scene-config list (`builtin_configs`, `*.toml` directly in CONFIG_DIR) does
not mistake them for scene configs."""

ACCURACY_CASES = ("bar", "spin", "recontact")
"""fracture_gs.paper.accuracy.CASES (listed here so that parsing a spec imports neither torch nor Warp)."""

MATERIAL_KEYS = tuple(f.name for f in dataclasses.fields(MaterialConfig))
_TOP_KEYS = ("sweep", "accuracy", "scene")
_SWEEP_KEYS = ("title", "warmup", "max_cells")
_ACCURACY_KEYS = ("label", "case", "cells", "cfl")
_SCENE_KEYS = (
    "label",
    "config",
    "variant",
    "cells",
    "dt",
    "cfl",
    "seed",
    "frames",
    "particles",
    "preset",
    "render",
    "material",
    "set",
)
MAX_CELLS_PER_AXIS = 4096  # grid cells across; 4096³ is far beyond any GPU
DEFAULT_MAX_CELLS = 10_000
"""Cells a spec may multiply out to unless `[sweep] max_cells` or `--max-cells` raises it: a scene cell's
config takes milliseconds to resolve, so 10,000 cells are about a minute of expansion before the first run."""


@dataclass(frozen=True)
class AccuracyBlock:
    """One `[[accuracy]]` table: the cross product case × cells × cfl."""

    cases: tuple[str, ...]
    """Cases of `fracture_gs.paper.accuracy.CASES`: bar, spin, recontact."""
    cells: tuple[int, ...]
    """Grid cells per metre [1/m]: Δx = 1/cells (bar needs a multiple of 4, so its ends sit on nodes)."""
    cfl: tuple[float, ...]
    """CFL numbers [unitless]: Δt = cfl·Δx / (wave speed + largest initial speed)."""
    label: str = "grid"
    """The block's name in tables and plots; `dx` is drawn as circles, anything else as triangles."""


@dataclass(frozen=True)
class SceneBlock:
    """One `[[scene]]` table: the cross product config × variant × cells × step × overrides × seed."""

    configs: tuple[str, ...]
    """Built-in config names or TOML/PLY paths (a relative path is looked up beside the spec first)."""
    variants: tuple[str, ...] = ()
    """Transfer variants; empty = each config's own `variants` list."""
    cells: tuple[Optional[int], ...] = (None,)
    """Grid cells across the config's explicit grid box (Δx = box side / cells; the grid shape follows,
    a fixed `sim.dt` scales with Δx so the CFL number stays put) or `capture.cells_across` for a PLY;
    None = the config's own Δx."""
    steps: tuple[Optional[tuple[str, float]], ...] = (None,)
    """Substeps: ("dt", seconds) = fixed Δt [s]; ("cfl", number) = adaptive Δt at that CFL number;
    None = the config's own."""
    seeds: tuple[int, ...] = (0,)
    """Seeds of the built-in asset's particle sampling and of `topology.seed` (Voronoi sites)."""
    overrides: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    """(dotted config key, values) pairs, e.g. ("material.E", (1e5, 2e5)): each adds an axis."""
    frames: Optional[int] = None
    """Frames to simulate; None = the config's `frames`."""
    particles: Optional[int] = None
    """Built-in scenes: particle count; None = the preset's."""
    preset: Optional[str] = None
    """`small` (Δx = 1/64) or `paper` (Δx = 1/128), applied before `cells`; None = the config's."""
    render: bool = False
    """Also render each cell as render-sim does (videos under OUT/cells/<id>/); off: metrics only."""
    label: str = "scene"
    """The block's name in tables."""


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep spec: what to run, before expansion into cells."""

    path: Path
    """The spec file."""
    source: str
    """The spec file as messages name it (relative to the working directory when inside it)."""
    title: str
    """Heading of sweep.md."""
    warmup: bool
    """Compile and load the kernels on each rank before its first cell, so no wall time includes them."""
    max_cells: int = DEFAULT_MAX_CELLS
    """The most cells the tables may multiply out to (`expand` refuses more, before making any) [cells]."""
    accuracy: tuple[AccuracyBlock, ...] = ()
    """`[[accuracy]]` tables in file order."""
    scenes: tuple[SceneBlock, ...] = ()
    """`[[scene]]` tables in file order."""


# --------------------------------------------------------------------------------------------
# finding and reading


def builtin_specs() -> list[str]:
    """Names of the built-in sweep specs."""
    return sorted(p.stem for p in SPEC_DIR.glob("*.toml")) if SPEC_DIR.is_dir() else []


def find_spec(name_or_path) -> Path:
    """A spec path, or a bare built-in name (`accuracy` → SPEC_DIR/accuracy.toml)."""
    text = os.fspath(name_or_path)
    path = Path(text).expanduser()
    if path.is_file():
        return path
    if len(path.parts) == 1:
        stem = path.stem if path.suffix == ".toml" else path.name
        if (SPEC_DIR / f"{stem}.toml").is_file():
            return SPEC_DIR / f"{stem}.toml"
    names = ", ".join(builtin_specs()) or "none installed"
    raise ConfigError(text, None, f"no such sweep spec; pass a path to a TOML file or a built-in name ({names}).")


def _display(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def load_spec(name_or_path) -> SweepSpec:
    """Read and check a sweep spec; raises ConfigError (one sentence) on the first problem."""
    path = find_spec(name_or_path)
    src = _display(path)
    if is_splat_file(path):
        raise ConfigError(
            src,
            None,
            "is a splat file (a captured scene), not a sweep spec; name it in a spec's [[scene]] table, e.g. "
            f'config = ["{path.name}"], and pass that spec.',
        )
    try:
        raw = tomllib.loads(path.read_bytes().decode("utf-8-sig"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(src, None, f"cannot be read as UTF-8 text ({exc}); check the file.") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(src, None, f"invalid TOML ({exc}); fix the syntax there.") from None
    _keys(src, "", raw, _TOP_KEYS)
    head = raw.get("sweep", {})
    if not isinstance(head, dict):
        raise ConfigError(src, "sweep", "sweep must be a table; write it as [sweep] with title and warmup keys.")
    _keys(src, "sweep", head, _SWEEP_KEYS)
    title = head.get("title", f"Sweep {path.stem}")
    if not isinstance(title, str):
        raise ConfigError(src, "sweep.title", f'sweep.title = {title!r} must be a string; write title = "My sweep".')
    warmup = head.get("warmup", True)
    if not isinstance(warmup, bool):
        raise ConfigError(src, "sweep.warmup", f"sweep.warmup = {warmup!r} must be true or false.")
    max_cells = head.get("max_cells", DEFAULT_MAX_CELLS)
    if not _is_int(max_cells) or max_cells < 1:
        raise ConfigError(
            src,
            "sweep.max_cells",
            f"sweep.max_cells = {max_cells!r} must be a positive integer; write it like max_cells = 20000.",
        )
    acc = tuple(_accuracy_block(src, f"accuracy[{i}]", t) for i, t in enumerate(_tables(src, raw, "accuracy")))
    scenes = tuple(_scene_block(src, f"scene[{i}]", t) for i, t in enumerate(_tables(src, raw, "scene")))
    if not acc and not scenes:
        raise ConfigError(
            src, None, "defines no cells; add an [[accuracy]] or a [[scene]] table (see `fracture-gs sweep --help`)."
        )
    return SweepSpec(
        path=path, source=src, title=title, warmup=warmup, max_cells=max_cells, accuracy=acc, scenes=scenes
    )


# --------------------------------------------------------------------------------------------
# value checks


def _keys(src: str, prefix: str, table: dict, valid) -> None:
    for key in table:
        if key not in valid:
            dotted = f"{prefix}.{key}" if prefix else key
            close = difflib.get_close_matches(key, list(valid), n=1)
            fix = f"did you mean {close[0]!r}?" if close else f"valid keys here: {', '.join(valid)}."
            raise ConfigError(src, dotted, f"{dotted} is not a sweep-spec key; {fix}")


def _tables(src: str, raw: dict, key: str) -> list:
    value = raw.get(key, [])
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
        raise ConfigError(src, key, f"{key} must be an array of tables; write each one as [[{key}]].")
    return value


def _list(src: str, key: str, value: Any) -> list:
    """A scalar or a non-empty list without repeats → list."""
    values = value if isinstance(value, list) else [value]
    if not values:
        raise ConfigError(src, key, f"{key} is an empty list; give at least one value or remove the key.")
    seen = []
    for v in values:
        if v in seen:
            raise ConfigError(src, key, f"{key} lists {v!r} twice; list each value once.")
        seen.append(v)
    return values


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _ints(src: str, key: str, value: Any, low: int, high: int, example: str) -> tuple[int, ...]:
    out = []
    for v in _list(src, key, value):
        if not _is_int(v) or not low <= v <= high:
            raise ConfigError(src, key, f"{key} value {v!r} must be an integer in [{low}, {high}]; {example}.")
        out.append(v)
    return tuple(out)


def _floats(src: str, key: str, value: Any, low: float, high: float, example: str) -> tuple[float, ...]:
    out = []
    for v in _list(src, key, value):
        if not _is_num(v) or not low < v <= high:
            raise ConfigError(src, key, f"{key} value {v!r} must be a number in ({low:g}, {high:g}]; {example}.")
        out.append(float(v))
    return tuple(out)


def _names(src: str, key: str, value: Any, options, example: str) -> tuple[str, ...]:
    out = []
    for v in _list(src, key, value):
        if v not in options:
            close = difflib.get_close_matches(str(v), list(options), n=1)
            fix = f"did you mean {close[0]!r}?" if close else f"choose from {', '.join(options)}; {example}."
            raise ConfigError(src, key, f"{key} value {v!r} is not one of {', '.join(options)}; {fix}")
        out.append(v)
    return tuple(out)


def _label(src: str, key: str, table: dict, default: str) -> str:
    label = table.get("label", default)
    if not isinstance(label, str) or not label.strip() or any(c in label for c in "|\n,"):
        raise ConfigError(src, key, f'{key} = {label!r} must be a short name without "|", "," or newlines.')
    return label


_TABLE_OWNS = {
    "variants": ("variant", True),
    "preset": ("preset", True),
    "topology.seed": ("seed", True),
    "frames": ("frames", False),
    "particles": ("particles", False),
    "sim.dt": ("dt", False),
    "sim.cfl": ("cfl", False),
    "sim.adaptive_dt": ("dt", False),
    "sim.dx": ("cells", False),
    "sim.grid_shape": ("cells", False),
    "capture.cells_across": ("cells", False),
}
"""[scene.set] key → (the table key that sets it, always): a cell applies the table key's value (`always`: every
cell, its default included; `variant` and `seed` are axes of their own, `preset` also rescales Δx), so the same
key in [scene.set] would be overwritten, or overwrite it, and one of the two would do nothing."""


def _refuse_shadowed(src: str, prefix: str, t: dict) -> None:
    """A config key set twice by one [[scene]] table: in [scene.material] and [scene.set], or in [scene.set] and by
    the table key that owns it (dt, cfl, cells, frames, ...). One of the two axes would do nothing."""
    material = t.get("material") or {}
    for key in t.get("set") or {}:
        if key.startswith("material.") and key[len("material.") :] in material:
            raise ConfigError(
                src,
                f"{prefix}.set.{key}",
                f"{prefix}.set.{key} sets {key}, which {prefix}.material.{key[len('material.') :]} sets too, so one "
                "of them would do nothing; give it once.",
            )
        owner, always = _TABLE_OWNS.get(key, (None, False))
        if key == "sim.adaptive_dt" and owner not in t and "cfl" in t:
            owner = "cfl"  # a cfl axis sets the adaptive step too: name the key the table holds
        if owner is not None and (always or owner in t):
            raise ConfigError(
                src,
                f"{prefix}.set.{key}",
                f"{prefix}.set.{key} sets what {prefix}.{owner} sets for every cell, so one of them would do nothing; "
                f"give the values as {prefix}.{owner} = [...] and remove {key} from [scene.set].",
            )


def _accuracy_block(src: str, prefix: str, t: dict) -> AccuracyBlock:
    _keys(src, prefix, t, _ACCURACY_KEYS)
    for key in ("case", "cells", "cfl"):
        if key not in t:
            example = {"case": 'case = ["bar"]', "cells": "cells = [16, 32]", "cfl": "cfl = [0.4]"}[key]
            raise ConfigError(src, f"{prefix}.{key}", f"{prefix}.{key} is missing; add it, e.g. {example}.")
    cases = _names(src, f"{prefix}.case", t["case"], ACCURACY_CASES, 'e.g. case = ["bar", "spin"]')
    cells = _ints(
        src, f"{prefix}.cells", t["cells"], 4, MAX_CELLS_PER_AXIS, "e.g. cells = [16, 32] for Δx = 1/16, 1/32"
    )
    if "bar" in cases:
        odd = [n for n in cells if n % 4]
        if odd:
            raise ConfigError(
                src,
                f"{prefix}.cells",
                f"{prefix}.cells value {odd[0]} puts the bar's ends (x = 0.25 and 0.75 m) between grid nodes; "
                "use a multiple of 4 for the bar case.",
            )
    cfl = _floats(src, f"{prefix}.cfl", t["cfl"], 0.0, 1.0, "e.g. cfl = [0.2, 0.4]")
    return AccuracyBlock(cases, cells, cfl, _label(src, f"{prefix}.label", t, "grid"))


def _scene_block(src: str, prefix: str, t: dict) -> SceneBlock:
    _keys(src, prefix, t, _SCENE_KEYS)
    if "config" not in t:
        raise ConfigError(
            src,
            f"{prefix}.config",
            f'{prefix}.config is missing; add it, e.g. config = ["bread"] (built-in names or paths).',
        )
    configs = []
    for v in _list(src, f"{prefix}.config", t["config"]):
        if not isinstance(v, str) or not v.strip():
            raise ConfigError(src, f"{prefix}.config", f"{prefix}.config value {v!r} must be a config name or path.")
        configs.append(v)
    variants = ()
    if "variant" in t:
        variants = _names(src, f"{prefix}.variant", t["variant"], VARIANT_NAMES, 'e.g. variant = ["baseline", "full"]')
    cells = (None,)
    if "cells" in t:
        cells = _ints(src, f"{prefix}.cells", t["cells"], 4, MAX_CELLS_PER_AXIS, "e.g. cells = [32, 64]")
    steps: list = []
    if "dt" in t:
        steps += [("dt", v) for v in _floats(src, f"{prefix}.dt", t["dt"], 0.0, 1.0, "e.g. dt = [1e-4, 5e-5]")]
    if "cfl" in t:
        steps += [("cfl", v) for v in _floats(src, f"{prefix}.cfl", t["cfl"], 0.0, 1.0, "e.g. cfl = [0.2, 0.4]")]
    seeds = _ints(src, f"{prefix}.seed", t.get("seed", 0), 0, 2**31 - 1, "e.g. seed = [0, 1, 2]")
    overrides = []
    material = t.get("material", {})
    if not isinstance(material, dict):
        raise ConfigError(src, f"{prefix}.material", f"{prefix}.material must be a table: [scene.material] E = [...].")
    _keys(src, f"{prefix}.material", material, MATERIAL_KEYS)
    for key, value in material.items():
        overrides.append((f"material.{key}", tuple(_list(src, f"{prefix}.material.{key}", value))))
    extra = t.get("set", {})
    if not isinstance(extra, dict):
        raise ConfigError(src, f"{prefix}.set", f'{prefix}.set must be a table: [scene.set] "sim.cfl" = [...].')
    for key, value in extra.items():
        if isinstance(value, dict):
            raise ConfigError(
                src,
                f"{prefix}.set.{key}",
                f'{prefix}.set.{key} is a table; quote the dotted key: "{key}.field" = [...].',
            )
        overrides.append((key, tuple(_list(src, f"{prefix}.set.{key}", value))))
    _refuse_shadowed(src, prefix, t)
    for key in ("frames", "particles", "preset"):  # one value per [[scene]] table: a list would keep only its first
        value = t.get(key)
        if isinstance(value, list) and len(value) != 1:
            raise ConfigError(
                src,
                f"{prefix}.{key}",
                f"{prefix}.{key} takes one value, not a list of {len(value)}; give one value, or one [[scene]] "
                "table per value.",
            )
    frames = t.get("frames")
    if frames is not None:
        frames = _ints(src, f"{prefix}.frames", frames, 1, 1_000_000, "e.g. frames = 10")[0]
    particles = t.get("particles")
    if particles is not None:
        particles = _ints(src, f"{prefix}.particles", particles, 1, 100_000_000, "e.g. particles = 2000")[0]
    preset = t.get("preset")
    if preset is not None:
        preset = _names(src, f"{prefix}.preset", preset, tuple(PRESETS), 'e.g. preset = "small"')[0]
    render = t.get("render", False)
    if not isinstance(render, bool):
        raise ConfigError(src, f"{prefix}.render", f"{prefix}.render = {render!r} must be true or false.")
    if render and any(s != 0 for s in seeds):
        raise ConfigError(
            src,
            f"{prefix}.seed",
            f"{prefix}.seed varies the asset sampling, which render = true (render-sim) keeps at seed 0; "
            "use render = false or seed = 0.",
        )
    return SceneBlock(
        configs=tuple(configs),
        variants=variants,
        cells=cells,
        steps=tuple(steps) or (None,),
        seeds=seeds,
        overrides=tuple(overrides),
        frames=frames,
        particles=particles,
        preset=preset,
        render=render,
        label=_label(src, f"{prefix}.label", t, "scene"),
    )
