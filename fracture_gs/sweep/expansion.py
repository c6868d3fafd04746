"""A parsed sweep spec → the ordered list of its cells, each with a stable id and, for a scene cell,
its resolved and validated scene config.

Order: tables in file order, each the cross product of its lists in key order (accuracy: case,
cells, cfl; scene: config, cells, step, overrides, seed, variant). Cells with the same canonical
parameters are one cell, listed once (at the first occurrence) under every label that produced it.

Stable ids: a cell's id is the first 12 hex digits of the SHA-256 of its canonical parameters
(JSON, sorted keys). An accuracy cell's are (case, cells, cfl); a scene cell's are (variant, seed,
render, and the fully resolved config as TOML), so editing a config, or a config it extends,
changes the id and the cell reruns, while a table label or the spec's own file name does not.

A scene cell's config: the spec's config (beside the spec first, then a path or a built-in name),
then preset → particles, frames → cells → step → material/set overrides → seed → variant, then the
config loader's own checks. A value that makes it invalid (e.g. `material.nu = 0.6`) is a
`ConfigError` naming the spec file, the table, the value and the fix, before anything runs.

Size: `count_cells` multiplies the tables' list lengths out without making a cell (it loads each named config
once, for its default variants), so a spec of millions of cells is refused at once: `iter_cells` (and `expand`)
raise a ConfigError when the count passes `spec.max_cells` (default 10,000; `[sweep] max_cells` or
`--max-cells` raises it). `iter_cells` yields the cells one by one, so `--list` prints them as they come.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Optional

from ..config import BUILTIN_SCENES
from ..errors import ConfigError
from ..io.config import apply_overrides, config_from_dict, config_to_dict, find_config
from ..io.config import load_config as load_scene_config
from ..io.config.dump import dump_dict
from ..io.detect import is_splat_file
from .spec import SceneBlock, SweepSpec


@dataclass
class Cell:
    """One independent run of the sweep."""

    index: int
    """Position in the expanded list (0-based); the order of the tables and of the progress lines."""
    id: str
    """12 hex digits of SHA-256 over `params`: the cache file is OUT/cells/<id>.json."""
    kind: str
    """`accuracy` or `scene`."""
    params: dict
    """Canonical parameters (what the id hashes; JSON values only)."""
    info: dict
    """Human-readable parameters for tables: case/cells/cfl, or config/variant/cells/step/set/seed."""
    labels: tuple[str, ...]
    """Labels of the spec tables that produced this cell (several when tables overlap)."""
    config: Optional[dict] = field(default=None, repr=False)
    """Scene cells: the resolved config as a TOML-shaped dict (`config_from_dict` rebuilds it)."""
    cost: float = 1.0
    """Estimated seconds on a GPU (`accuracy_cost` / `scene_cost`): only its ratios matter, for dealing
    cells out so that ranks finish together."""

    @property
    def describe(self) -> str:
        """A short line for progress output and `--list`."""
        i = self.info
        if self.kind == "accuracy":
            return f"{i['case']} Δx=1/{i['cells']} CFL {i['cfl']:g}"
        parts = [i["config"], i["variant"]]
        if i.get("cells") is not None:
            parts.append(f"cells {i['cells']}")
        if i.get("step"):
            parts.append(i["step"])
        if i.get("set"):
            parts.append(i["set"])
        parts.append(f"seed {i['seed']}")
        return " ".join(str(p) for p in parts)


def cell_id(params: dict) -> str:
    """12 hex digits of SHA-256 over the canonical JSON of `params`."""
    text = json.dumps(params, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def count_cells(spec: SweepSpec) -> tuple[int, list[tuple[str, int]]]:
    """(cells the tables multiply out to, [(table, its count)]) without making any cell: an upper bound on
    `len(expand(spec))` (cells repeated across tables are merged there). Loads each named scene config once."""
    per: list[tuple[str, int]] = []
    for i, block in enumerate(spec.accuracy):
        per.append((f"accuracy[{i}]", len(block.cases) * len(block.cells) * len(block.cfl)))
    bases: dict[str, Any] = {}
    for b, block in enumerate(spec.scenes):
        prefix = f"scene[{b}]"
        settings = math.prod(len(v) for _, v in block.overrides)
        total = 0
        for name in block.configs:
            variants = block.variants or tuple(_base_config(spec, prefix, name, bases).variants)
            total += len(block.cells) * len(block.steps) * settings * len(block.seeds) * len(variants)
        per.append((prefix, total))
    return sum(n for _, n in per), per


def check_size(spec: SweepSpec, max_cells: Optional[int] = None) -> int:
    """The spec's cell count (`count_cells`), or ConfigError when it passes the cap (`max_cells`, else
    `spec.max_cells`): one sentence with the count, the largest table and how to raise the cap."""
    cap = spec.max_cells if max_cells is None else max_cells
    total, per = count_cells(spec)
    if total > cap:
        table, n = max(per, key=lambda t: t[1])
        raise ConfigError(
            spec.source,
            "sweep.max_cells",
            f"the tables multiply out to {total:,} cells ({table}: {n:,}), over the cap sweep.max_cells = {cap:,}; "
            f"list fewer values (each list multiplies the count) or split the spec, or raise the cap with "
            f"max_cells = {total} in [sweep] or --max-cells {total}.",
        )
    return total


def expand(
    spec: SweepSpec, max_cells: Optional[int] = None, progress: Optional[Callable[[int, int], None]] = None
) -> list[Cell]:
    """Every cell of the spec in order (tables in file order, each a cross product in key order),
    duplicates merged into the first occurrence; ConfigError when there are more than the cap (`check_size`)."""
    return list(iter_cells(spec, max_cells, progress))


def iter_cells(
    spec: SweepSpec, max_cells: Optional[int] = None, progress: Optional[Callable[[int, int], None]] = None
) -> Iterator[Cell]:
    """`expand`, one cell at a time (the size check comes first, before any cell is made). A cell repeated by
    a later table is yielded once, at its first occurrence; the later table's label is added to that same
    Cell object. `progress(made, total)` is called after each cell made."""
    total = check_size(spec, max_cells)
    cells: dict[str, Cell] = {}
    made = [0]

    def add(kind: str, params: dict, info: dict, label: str, config: Optional[dict] = None, cost: float = 1.0):
        made[0] += 1
        if progress is not None:
            progress(made[0], total)
        cid = cell_id(params)
        if cid in cells:
            if label not in cells[cid].labels:
                cells[cid].labels += (label,)
            return None
        cells[cid] = Cell(len(cells), cid, kind, params, info, (label,), config, cost)
        return cells[cid]

    for block in spec.accuracy:
        for case, n, cfl in itertools.product(block.cases, block.cells, block.cfl):
            params = {"kind": "accuracy", "case": case, "cells": n, "cfl": cfl}
            info = {"case": case, "cells": n, "cfl": cfl}
            cell = add("accuracy", params, info, block.label, None, accuracy_cost(case, n, cfl))
            if cell is not None:
                yield cell
    bases: dict[str, Any] = {}
    plain: dict[tuple, dict] = {}
    for b, block in enumerate(spec.scenes):
        prefix = f"scene[{b}]"
        for name in block.configs:
            base = _base_config(spec, prefix, name, bases)
            variants = block.variants or tuple(base.variants)
            keys = [k for k, _ in block.overrides]
            combos = itertools.product(block.cells, block.steps, itertools.product(*[v for _, v in block.overrides]))
            for n, step, values in combos:
                setting = dict(zip(keys, values))
                for seed, variant in itertools.product(block.seeds, variants):
                    cfg = scene_config(spec, prefix, name, base, block, n, step, setting, seed, variant, plain)
                    resolved = config_to_dict(cfg)
                    params = {
                        "kind": "scene",
                        "variant": variant,
                        "seed": seed,
                        "render": block.render,
                        "config": dump_dict(resolved),
                    }
                    info = {
                        "config": name,
                        "scene": cfg.scene,
                        "variant": variant,
                        "cells": n,
                        "dx": cfg.sim.dx,
                        "step": None if step is None else f"{step[0]}={step[1]:g}",
                        "set": ", ".join(f"{k}={_short(v)}" for k, v in setting.items()),
                        "seed": seed,
                        "frames": cfg.frames,
                        "render": block.render,
                    }
                    cell = add("scene", params, info, block.label, resolved, scene_cost(cfg))
                    if cell is not None:
                        yield cell


SECONDS_PER_SUBSTEP = 0.35e-3  # a GPU substep on a few thousand particles: launch-bound, about flat up to 50k
SECONDS_PER_FRAME = 0.01  # per-frame checks and diagnostics
PARTICLES_PER_UNIT_COST = 2e5  # particles at which a substep costs twice the launch-bound time


def _cost(substeps: float, particles: float, frames: float) -> float:
    return SECONDS_PER_SUBSTEP * substeps * (1 + particles / PARTICLES_PER_UNIT_COST) + SECONDS_PER_FRAME * frames


def accuracy_cost(case: str, cells: int, cfl: float) -> float:
    """Estimated seconds of an accuracy cell: substeps = duration · (c + v) / (CFL · Δx) with the case's
    P-wave speed c, particles = 8 per cell (2 per axis) over the body's volume (paper/accuracy.py)."""
    from ..paper import accuracy as A

    if case == "bar":
        c, duration, volume, frames = math.sqrt(A.BAR["E"] / A.BAR["rho"]), A.BAR["periods"] * 0.1, 0.5 * 0.0625**2, 0
    elif case == "spin":
        c = A.p_wave(A.SPIN["E"], A.SPIN["nu"], A.SPIN["rho"]) + A.SPIN["omega"] * A.SPIN["a"] / 2
        duration, volume, frames = A.SPIN["T"], A.SPIN["a"] ** 3, 0  # sampled inside one loop, no frames
    else:
        c = A.p_wave(A.RECONTACT["E"], 0.3, A.RECONTACT["rho"]) + A.RECONTACT["speed"]
        duration, frames = A.RECONTACT["frames"] * A.RECONTACT["frame_dt"], A.RECONTACT["frames"]
        volume = 7.4e-4
    return _cost(duration * c * cells / cfl, 8 * volume * cells**3, frames)


def scene_cost(cfg) -> float:
    """Estimated seconds of a scene cell from its config: frames × substeps per frame (the fixed Δt, or the
    CFL step of the stiffest default material when adaptive) and its particle count."""
    from ..paper.accuracy import p_wave

    m, s = cfg.material, cfg.sim
    dt = s.dt
    if s.adaptive_dt:
        dt = min(dt, s.cfl * s.dx / max(p_wave(m.E, m.nu, m.density), 1e-9))
    substeps = cfg.frames * max(1.0, cfg.frame_dt / max(dt, 1e-12))
    return _cost(substeps, cfg.particles or 20_000, cfg.frames)


def _short(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _base_config(spec: SweepSpec, prefix: str, name: str, cache: dict):
    """A scene config named by the spec: beside the spec first, then find_config (paths, built-ins)."""
    if name not in cache:
        local = spec.path.parent / name
        try:
            cache[name] = load_scene_config(local if local.is_file() else find_config(name))
        except ConfigError as exc:
            raise ConfigError(
                spec.source,
                f"{prefix}.config",
                _sentence(f"{prefix}.config value {name!r} cannot be loaded: {_inner(exc)}"),
            ) from None
    return cache[name]


def _set_dotted(d: dict, key: str, value: Any) -> None:
    """d["a"]["b"][0]["c"] = value for key "a.b.0.c" (missing tables are created)."""
    parts = key.split(".")
    node: Any = d
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise KeyError(".".join(parts[: i + 1]))
            node = node[int(part)]
        else:
            node = node.setdefault(part, {})
        if not isinstance(node, (dict, list)):
            raise KeyError(".".join(parts[: i + 1]))
    last = parts[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise KeyError(key)
        node[int(last)] = value
    else:
        node[last] = value


def scene_config(
    spec,
    prefix,
    name,
    base,
    block: SceneBlock,
    cells,
    step,
    setting: dict,
    seed: int,
    variant: str,
    plain: Optional[dict] = None,
):
    """The validated SceneConfig of one scene cell (preset → particles, frames → cells → step →
    material/set overrides → seed → variant). `plain`: a cache of the base configs as dicts, per name and
    preset, shared by the cells of one expansion."""
    what = f"{prefix} ({name}, {variant}" + "".join(f", {k} = {_short(v)}" for k, v in setting.items()) + ")"
    try:
        key = (name, block.preset)
        if plain is None or key not in plain:
            cfg = base if block.preset is None else apply_overrides(base, preset=block.preset, source=spec.source)
            d0 = config_to_dict(cfg)
            if plain is not None:
                plain[key] = d0
        d = copy.deepcopy(plain[key] if plain is not None else d0)
        if block.particles is not None:
            d["particles"] = block.particles
        if block.frames is not None:
            d["frames"] = block.frames
        if cells is not None:
            _apply_cells(d, cells, prefix, spec.source)
        if step is not None:
            d["sim"]["adaptive_dt"] = step[0] == "cfl"
            d["sim"]["dt" if step[0] == "dt" else "cfl"] = step[1]
        d.setdefault("topology", {})["seed"] = seed
        for key, value in setting.items():
            try:
                _set_dotted(d, key, value)
            except KeyError as missing:
                raise ConfigError(
                    spec.source,
                    f"{prefix}.set.{key}",
                    f"{prefix} override {key!r}: the config has no entry {missing.args[0]!r}; "
                    "check the dotted path (array entries by index, e.g. material_map.0.E).",
                ) from None
        d["variants"] = [variant]
        return config_from_dict(d, source="")
    except ConfigError as exc:
        if exc.source == spec.source:
            raise
        raise ConfigError(
            spec.source, prefix, _sentence(f"{what} gives an invalid scene config: {_inner(exc)}")
        ) from None


def _inner(exc: Exception) -> str:
    """An embedded error sentence, on one line, without a final full stop (the outer sentence adds one)."""
    text = " ".join(str(exc).split())
    return text[:-1] if text.endswith(".") else text


def _sentence(text: str) -> str:
    """`text` ending in exactly one stop."""
    return text if text.endswith((".", "?", "!")) else text + "."


def _apply_cells(d: dict, cells: int, prefix: str, source: str) -> None:
    """Δx = box side / cells for an explicit grid (shape and a fixed dt follow); a PLY's cells_across."""
    scene = str(d.get("scene", ""))
    if scene not in BUILTIN_SCENES and is_splat_file(scene):
        d.setdefault("capture", {})["cells_across"] = cells
        return
    sim = d["sim"]
    if sim.get("grid", "explicit") != "explicit":
        raise ConfigError(
            source,
            f"{prefix}.cells",
            f'{prefix}.cells needs an explicit grid (sim.grid = "explicit") or a captured scene (a splat file); '
            'remove cells or set sim.grid = "explicit" in the config.',
        )
    dx = float(sim["dx"])
    side = max(sim["grid_shape"]) * dx
    new_dx = side / cells
    ratio = new_dx / dx
    sim["grid_shape"] = [max(4, round(n / ratio)) for n in sim["grid_shape"]]
    sim["dx"] = new_dx
    sim["dt"] = float(sim["dt"]) * ratio
