"""Value checks of a SceneConfig: one sentence naming the source, the field and the fix, on the first problem."""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from typing import Any, Sequence

from ...config import (
    BUILTIN_SCENES,
    GRID_KINDS,
    MATERIALS,
    PLANE_MODES,
    PRESETS,
    PROVIDERS,
    REGION_KINDS,
    RENDER_BACKENDS,
    RENDER_MODES,
    CuboidBoundary,
    MaterialMapEntry,
    ParticleRegion,
    PlaneBoundary,
    RenderConfig,
    SceneConfig,
    SimConfig,
    SphereBoundary,
    TopologyConfig,
)
from ...errors import ConfigError
from ...variants import VARIANT_NAMES, variant_spec
from ..detect import is_splat_file
from .combinations import check_combinations

MAX_FIELD_SLOTS = 8  # sim.storage.MAX_SLOTS (io does not import sim)
MAX_IMAGE_SIDE = 8192  # pixels; larger frames exceed H.264 levels and the rasterizers' tile budgets
MAX_PARTICLES = 100_000_000  # a built-in asset's particle count (≈ 20 GB of state on the GPU)
MAX_FRAMES = 1_000_000
MIN_CAPTURE_SIZE = 1e-3  # m: capture.size; a millimetre object is a few cells of any grid
MAX_CAPTURE_SIZE = 100.0  # m: capture.size; the presets are tuned at 0.5 m, a building is not an object
PROBE_VOXELS = 128  # capture.resolution.PROBE_CELLS (io does not import capture): voxels across the object
MAX_FILL_CLOSING = PROBE_VOXELS // 16  # voxels; 8 already bridges holes 16 voxels wide, and the cost grows as k³
MAX_OUTLIER_NEIGHBOURS = 256  # a k-d tree query of k neighbours holds N·k distances
MAX_LOAD_SPEED = 100.0  # m/s; the stiffest preset's P-wave speed is ≈ 15 m/s
MAX_OFFSET = 100.0  # m; float32 positions keep ≈ 8 µm steps there, far below a cell
MAX_SPEED = 1e4  # m/s: an initial velocity (a rifle bullet is 1e3); above it the CFL step underflows float32
ROTATION_TOLERANCE = 1e-3  # max |RᵀR − I| of capture.rotation and a camera's rotation (4 written digits pass)
_SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+ -]{0,127}")


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
            self.fail(
                f"{prefix}.lower",
                f"{prefix}.lower {list(lower)} is not below {prefix}.upper {list(upper)} on every axis",
                "swap or fix the corners so lower < upper",
            )

    def interval(self, prefix: str, start: float, end: float) -> None:
        if not (0 <= start <= end):
            self.fail(
                f"{prefix}.start",
                f"{prefix}.start = {start!r} and end = {end!r} do not form a time interval",
                "use 0 <= start <= end (seconds)",
            )


MAX_FPS = 1000
"""Frames per second: the fastest playback rate render.fps may ask of the videos (100,000 was written as is)."""
MAX_GRAVITY = 1.0e4
"""m/s²: the largest |sim.gravity| (about 1,000 g; beyond it every scene tears apart in its first substeps)."""


def is_finite_number(v) -> bool:
    """A number read from TOML or JSON that a check can compute with: an int or float, not a boolean, finite as a
    float (a 400-digit JSON integer overflows float() and is not)."""
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def validate(cfg: SceneConfig, source: str = "<config>") -> SceneConfig:
    """Check every value of a SceneConfig; raise ConfigError (one sentence) on the first problem."""
    c = _Checker(source)
    _check_finite(c, cfg, "")
    _check_scene(c, cfg)
    _check_material(c, "material", cfg.material)
    _check_sim(c, cfg.sim, cfg.frame_dt)
    _check_material_map(c, cfg.material_map)
    _check_topology(c, cfg.topology, cfg.frames)
    _check_render(c, cfg.render)
    _check_capture(c, cfg.capture, cfg.sim.boundaries)
    check_combinations(c, cfg)
    _check_provider_needed(c, cfg)
    if cfg.scene in BUILTIN_SCENES:  # a captured scene's Δx and material are chosen later (capture.resolve)
        _check_wave_substeps(c, cfg)
    return cfg


def _check_wave_substeps(c: _Checker, cfg: SceneConfig) -> None:
    """With adaptive_dt each substep is at most cfl·Δx / c, c = √((λ+2μ)/ρ) the P-wave speed: a modulus (or a
    density) that makes a frame need more than sim.max_substeps_per_frame substeps is refused here, naming the
    key, instead of by the first frame ("needs 131266027842848 substeps") after the scene was built."""
    s = cfg.sim
    if not s.adaptive_dt:
        return
    m = cfg.material
    sources = [("material", m.E, m.nu, m.density)] + [
        (f"material_map[{i}]", e.E or m.E, m.nu if e.nu is None else e.nu, e.density or m.density)
        for i, e in enumerate(cfg.material_map)
    ]
    for key, E, nu, rho in sources:
        if not (0 < E and -1 < nu < 0.5 and 0 < rho):
            continue  # the range checks name these
        speed = math.sqrt((E * nu / ((1 + nu) * (1 - 2 * nu)) + E / (1 + nu)) / rho)
        n = math.ceil(cfg.frame_dt / min(s.dt, s.cfl * s.dx / speed) - 1e-9)
        if n > s.max_substeps_per_frame:
            c.fail(
                f"{key}.E",
                f"{key}.E = {E:g} Pa at density {rho:g} kg/m³ is a wave speed of {speed:.3g} m/s, so a frame of "
                f"{cfg.frame_dt:g} s at Δx = {s.dx:g} m needs {n:,} substeps, over sim.max_substeps_per_frame = "
                f"{s.max_substeps_per_frame:,}",
                "lower the modulus (or raise the density, sim.dx or sim.max_substeps_per_frame)",
            )


def _check_capture(c: _Checker, cap, cfg_boundaries=()) -> None:
    """Every [capture] key: clean-up, region of interest, fit, resolution, fill, load, camera and regions
    (types and NaN are checked before; here the ranges and the keys that only mean something together)."""
    c.within("capture.min_opacity", cap.min_opacity, 0.0, 1.0, "use an opacity in [0, 1), e.g. 0.01", open_high=True)
    c.within(
        "capture.outlier_neighbours",
        cap.outlier_neighbours,
        0,
        MAX_OUTLIER_NEIGHBOURS,
        f"use 0 (off) to {MAX_OUTLIER_NEIGHBOURS} neighbours, e.g. 8",
    )
    c.positive("capture.outlier_std", cap.outlier_std, "give a number of standard deviations, e.g. outlier_std = 3")
    c.within("capture.percentile", cap.percentile, 0.0, 50.0, "use a percentile in [0, 50), e.g. 1", open_high=True)
    c.within(
        "capture.size",
        cap.size,
        MIN_CAPTURE_SIZE,
        MAX_CAPTURE_SIZE,
        f"give the object's longest side in metres, {MIN_CAPTURE_SIZE:g} to {MAX_CAPTURE_SIZE:g} (the presets are "
        "tuned at 0.5)",
    )
    if cap.cells_across is not None:
        c.within("capture.cells_across", cap.cells_across, 4, 1024, "use 4 to 1024 cells across the object")
    if cap.max_particles is not None:
        c.within(
            "capture.max_particles",
            cap.max_particles,
            1,
            MAX_PARTICLES,
            f"give a fill budget of 1 to {MAX_PARTICLES:,} particles, or leave it unset",
        )
    c.positive("capture.fill_threshold", cap.fill_threshold, "give a voxel density above 0, e.g. fill_threshold = 0.2")
    c.within(
        "capture.fill_closing",
        cap.fill_closing,
        0,
        MAX_FILL_CLOSING,
        f"use 0 to {MAX_FILL_CLOSING} voxels (k voxels bridge holes 2k wide: {MAX_FILL_CLOSING} spans an eighth of "
        f"the {PROBE_VOXELS}-voxel probe grid across the object, and the cost grows as k³)",
    )
    c.within(
        "capture.load_speed",
        cap.load_speed,
        0.0,
        MAX_LOAD_SPEED,
        f"use 0 (automatic) or a speed up to {MAX_LOAD_SPEED:g} m/s",
    )
    c.at_least("capture.view", cap.view, 0, "use the index of a view in cameras.json, from 0")
    _check_unused_capture_keys(c, cap, bool(cfg_boundaries))
    if cap.cameras_json is not None and not cap.cameras_json.strip():
        c.fail("capture.cameras_json", "capture.cameras_json is empty", "give the path of the trainer's cameras.json")
    if cap.cameras_json is not None and "\x00" in cap.cameras_json:
        c.fail("capture.cameras_json", "capture.cameras_json holds a NUL character, which no path can", "fix the path")
    _check_roi(c, cap)
    _check_fit(c, cap)
    for i, r in enumerate(cap.regions):
        p = f"capture.regions[{i}]"
        if not all(lo < hi for lo, hi in zip(r.lower, r.upper)):
            c.fail(
                p,
                f"{p} has lower = {list(r.lower)} not below upper = {list(r.upper)} on every axis",
                "give a box with lower < upper on x, y and z (scene units)",
            )
        if r.material == "config":
            c.fail(f"{p}.material", f'{p}.material = "config" names no preset', "use ceramic, wood, plant or bread")


def _check_unused_capture_keys(c: _Checker, cap, has_boundaries: bool) -> None:
    """Keys the rest of [capture] would make do nothing (a value only the default leaves unnoticed): a view
    without the trainer camera, a load speed without a load, a ground level with the ground turned off."""
    if cap.view != 0 and cap.camera == "auto":
        c.fail(
            "capture.view",
            f'capture.view = {cap.view} picks a trainer view, but capture.camera = "auto" frames the object itself',
            'set capture.camera = "trainer" to use that view, or remove capture.view',
        )
    if cap.load_speed != 0 and (cap.load == "none" or has_boundaries):
        why = "capture.load = 'none' adds no load" if cap.load == "none" else "the config's sim.boundaries are its load"
        c.fail(
            "capture.load_speed",
            f"capture.load_speed = {cap.load_speed:g} has no effect: {why}",
            "choose a capture.load (pull, drop, impact, shoot or crush), or remove capture.load_speed",
        )
    if cap.ground == "none" and cap.ground_level is not None:
        c.fail(
            "capture.ground_level",
            f'capture.ground_level = {cap.ground_level:g} is set but capture.ground = "none" keeps every Gaussian',
            'set capture.ground = "auto" to cut the ground there, or remove capture.ground_level',
        )


def _check_roi(c: _Checker, cap) -> None:
    """The ROI keys that `capture.roi` uses are given and sound; the ones it would ignore are refused."""
    uses = {"box": ("roi_lower", "roi_upper"), "sphere": ("roi_center", "roi_radius")}.get(cap.roi, ())
    for key in ("roi_lower", "roi_upper", "roi_center", "roi_radius"):
        given = getattr(cap, key) is not None
        if given and key not in uses:
            kind = "box" if key in ("roi_lower", "roi_upper") else "sphere"
            c.fail(
                f"capture.{key}",
                f"capture.{key} is set but capture.roi = {cap.roi!r} ignores it",
                f'set capture.roi = "{kind}" to use it, or remove capture.{key}',
            )
        if not given and key in uses:
            c.fail(
                f"capture.{key}",
                f"capture.roi = {cap.roi!r} needs capture.{key}",
                'add it (scene units), or set capture.roi = "auto"',
            )
    if cap.roi == "box" and not all(lo < hi for lo, hi in zip(cap.roi_lower, cap.roi_upper)):
        c.fail(
            "capture.roi_lower",
            f"capture.roi_lower = {list(cap.roi_lower)} is not below capture.roi_upper = {list(cap.roi_upper)} on "
            "every axis",
            "give a box with roi_lower < roi_upper on x, y and z (scene units)",
        )
    if cap.roi == "sphere":
        c.positive("capture.roi_radius", cap.roi_radius, "give the sphere's radius in scene units")


def _check_fit(c: _Checker, cap) -> None:
    """capture.scale, rotation and offset (each honoured alone or together): a positive scale, a proper
    rotation (orthonormal, det = +1), an offset within float32's comfortable range."""
    if not cap.fit:
        for key in ("scale", "rotation", "offset"):
            if getattr(cap, key) is not None:
                c.fail(
                    f"capture.{key}",
                    f"capture.{key} is set but capture.fit = false uses the file's coordinates as written",
                    f"set capture.fit = true to use it, or remove capture.{key}",
                )
    if cap.scale is not None:
        c.positive("capture.scale", cap.scale, "give metres per scene unit above 0, or remove it (automatic)")
    if cap.offset is not None and not all(abs(v) <= MAX_OFFSET for v in cap.offset):
        c.fail(
            "capture.offset",
            f"capture.offset = {list(cap.offset)} is more than {MAX_OFFSET:g} m from the origin",
            f"keep each component within ±{MAX_OFFSET:g} m (positions are float32 in the solver), or remove it",
        )
    if cap.rotation is not None:
        R = cap.rotation
        err = max(
            abs(sum(R[k][i] * R[k][j] for k in range(3)) - (1.0 if i == j else 0.0)) for i in range(3) for j in range(3)
        )
        if err > ROTATION_TOLERANCE:
            c.fail(
                "capture.rotation",
                f"capture.rotation = {[list(r) for r in R]} is not a rotation (RᵀR differs from the identity by "
                f"{err:.3g})",
                "give an orthonormal 3×3 matrix (rows of unit length, at right angles), or remove it (automatic)",
            )
        det = (
            R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1])
            - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0])
            + R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0])
        )
        if det < 0:
            c.fail(
                "capture.rotation",
                f"capture.rotation = {[list(r) for r in R]} is a reflection (determinant {det:.3g})",
                "negate one row to make it a proper rotation (determinant +1), or remove it (automatic)",
            )


def _check_finite(c: _Checker, value: Any, field: str) -> None:
    """Every float of the config tree (scalars and vector components) is finite: NaN or inf never
    reaches the solver, whatever the field. It runs first, so the per-field checks below may assume
    finite values."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            _check_finite(c, getattr(value, f.name), f"{field}.{f.name}" if field else f.name)
    elif isinstance(value, (list, tuple)):
        if value and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            if not all(math.isfinite(v) for v in value):
                c.fail(field, f"{field} = {list(value)} is not finite", "give finite numbers (no nan or inf)")
        else:
            for i, v in enumerate(value):
                _check_finite(c, v, f"{field}[{i}]")
    elif isinstance(value, float) and not math.isfinite(value):
        c.fail(
            field, f"{field} = {value!r} is not a finite number", "give a finite value (nan and inf are not allowed)"
        )


def _check_scene(c: _Checker, cfg: SceneConfig) -> None:
    if not isinstance(cfg.name, str) or not _SAFE_NAME.fullmatch(cfg.name) or cfg.name.strip() != cfg.name:
        c.fail(
            "name",
            f"name = {cfg.name!r} cannot be used as a folder name under runs/",
            "start with a letter, digit or '_' and use letters, digits, '_', '-', '+', '.' or spaces (≤ 128)",
        )
    if cfg.scene not in BUILTIN_SCENES and not is_splat_file(cfg.scene):
        c.fail(
            "scene",
            f"scene = {cfg.scene!r} is neither a built-in scene nor a splat file",
            f"use one of {', '.join(BUILTIN_SCENES)} or a path to a .ply, .compressed.ply, .splat or .spz scene",
        )
    c.choice("preset", cfg.preset, list(PRESETS))
    c.within("frames", cfg.frames, 1, MAX_FRAMES, f"simulate 1 to {MAX_FRAMES:,} frames")
    if cfg.particles is not None:
        c.within("particles", cfg.particles, 1, MAX_PARTICLES, f"use 1 to {MAX_PARTICLES:,} particles")
    c.positive("frame_dt", cfg.frame_dt, "give the time between frames in seconds, e.g. frame_dt = 0.01")
    if math.sqrt(sum(v * v for v in cfg.initial_velocity)) > MAX_SPEED:
        c.fail(
            "initial_velocity",
            f"initial_velocity = {list(cfg.initial_velocity)} is faster than {MAX_SPEED:g} m/s",
            f"give a velocity in m/s up to {MAX_SPEED:g} (the substep shrinks with the speed: Δt ≤ CFL·Δx / |v|)",
        )
    if cfg.material_property is not None and not cfg.material_property:
        c.fail(
            "material_property",
            "material_property is empty",
            "name the PLY property holding the labels or remove the key",
        )
    _check_variants(c, cfg)


def _check_variants(c: _Checker, cfg: SceneConfig) -> None:
    if not cfg.variants:
        c.fail("variants", "variants is empty", f"list at least one of {', '.join(VARIANT_NAMES)}")
    for i, v in enumerate(cfg.variants):
        c.choice(f"variants[{i}]", v, VARIANT_NAMES)
    if len(set(cfg.variants)) != len(cfg.variants):
        c.fail("variants", f"variants {cfg.variants} lists a variant twice", "list each variant once")


def _check_provider_needed(c: _Checker, cfg: SceneConfig) -> None:
    """Every variant but baseline needs fragment labels, hence an event provider."""
    needing = [v for v in cfg.variants if variant_spec(v).needs_provider]
    if needing and cfg.topology.provider == "none":
        c.fail(
            "topology.provider",
            f"variants {needing} need a fracture event provider but topology.provider = 'none'",
            'set topology.provider = "stress" or "oracle", or run only baseline',
        )


def _check_sim(c: _Checker, s: SimConfig, frame_dt: float) -> None:
    c.positive("sim.dt", s.dt, "give the substep in seconds, e.g. dt = 1e-4")
    if s.dt > frame_dt:
        c.fail(
            "sim.dt",
            f"sim.dt = {s.dt!r} is longer than frame_dt = {frame_dt!r}",
            "use a substep no longer than one frame",
        )
    if frame_dt / s.dt > s.max_substeps_per_frame * (1 + 1e-9):  # Δt bounds the adaptive step too
        c.fail(
            "sim.max_substeps_per_frame",
            f"frame_dt / sim.dt = {frame_dt / s.dt:{'.0f' if frame_dt / s.dt < 1e12 else '.3g'}} substeps exceeds "
            f"sim.max_substeps_per_frame = {s.max_substeps_per_frame}",
            "raise max_substeps_per_frame or sim.dt",
        )
    c.within("sim.cfl", s.cfl, 1e-12, 1.0, "use a CFL number in (0, 1], e.g. cfl = 0.4")
    g = math.hypot(*(float(v) for v in s.gravity))
    if g > MAX_GRAVITY:  # 1e300 passed and the first frame diverged (exit 1) after the scene was built
        c.fail(
            "sim.gravity",
            f"sim.gravity = {list(s.gravity)} is {g:.3g} m/s², over {MAX_GRAVITY:,.0f} m/s² (about 1,000 g)",
            "give the acceleration in m/s², e.g. gravity = [0.0, 0.0, -9.8]",
        )
    c.choice("sim.variant", s.variant, VARIANT_NAMES)
    c.choice("sim.grid", s.grid, GRID_KINDS)
    c.positive("sim.dx", s.dx, "give the grid spacing in metres, e.g. dx = 0.015625")
    c.at_least("sim.wall_cells", s.wall_cells, 0, "use 0 or more cells")
    for i, n in enumerate(s.grid_shape):
        if n < max(5, 2 * s.wall_cells + 2):
            c.fail(
                f"sim.grid_shape[{i}]",
                f"sim.grid_shape[{i}] = {n} is too small for the B-spline stencil and {s.wall_cells} wall cells",
                f"use at least {max(5, 2 * s.wall_cells + 2)} nodes per axis",
            )
    c.at_least("sim.grid_margin", s.grid_margin, 0.0, "use a non-negative fraction, e.g. grid_margin = 0.5")
    c.at_least("sim.max_grid_cells", s.max_grid_cells, 125, "allow at least 5×5×5 nodes")
    nodes = s.grid_shape[0] * s.grid_shape[1] * s.grid_shape[2]
    if s.grid == "explicit" and nodes > s.max_grid_cells:
        c.fail(
            "sim.grid_shape",
            f"sim.grid_shape = {list(s.grid_shape)} is {nodes:,} nodes, over sim.max_grid_cells = "
            f"{s.max_grid_cells:,} (≈ {nodes * 32 / 2**30:.3g} GiB of grid buffers)",
            "use a coarser grid (raise sim.dx, fewer nodes) or raise sim.max_grid_cells if the memory is there",
        )
    if s.grid_bounds is not None:
        c.box("sim.grid_bounds", s.grid_bounds[0], s.grid_bounds[1])
    c.choice("sim.material", s.material, MATERIALS)
    c.within("sim.restitution", s.restitution, 0.0, 1.0, "use a restitution in [0, 1]")
    c.at_least("sim.eps_mass", s.eps_mass, 0.0, "use a non-negative threshold, e.g. eps_mass = 1e-3")
    c.at_least("sim.eps_band", s.eps_band, 0.0, "use a non-negative threshold, e.g. eps_band = 1e-3")
    c.at_least("sim.max_substeps_per_frame", s.max_substeps_per_frame, 1, "use a positive bound")
    c.within("sim.field_slots", s.field_slots, 2, MAX_FIELD_SLOTS, f"use 2 to {MAX_FIELD_SLOTS} fields per node")
    c.within("sim.max_fragments", s.max_fragments, 2, 4096, "use 2 to 4096 fragments")
    c.at_least("sim.contact.friction", s.contact.friction, 0.0, "use a non-negative Coulomb coefficient")
    c.positive("sim.contact.fill", s.contact.fill, "use a fraction of a full node's mass, e.g. fill = 0.5")
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
    elif isinstance(b, SphereBoundary):
        c.positive(f"{p}.radius", b.radius, "give the sphere's radius in metres, e.g. radius = 0.06")
        c.interval(p, b.start, b.end)
    elif isinstance(b, ParticleRegion):
        c.choice(f"{p}.kind", b.kind, REGION_KINDS)
        c.box(p, b.lower, b.upper)
        c.interval(p, b.start, b.end)
    else:
        c.fail(
            p,
            f"{p} is a {type(b).__name__}, not a boundary",
            "use PlaneBoundary, CuboidBoundary, SphereBoundary or ParticleRegion",
        )


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
        c.fail(
            "topology.latch_frame",
            f"topology.latch_frame = {t.latch_frame} is after the last frame ({frames})",
            "latch within the run or raise frames",
        )
    if t.latch_time is not None:
        c.at_least("topology.latch_time", t.latch_time, 0.0, "use a time in seconds >= 0")
    c.at_least("topology.min_particles", t.min_particles, 1, "need at least one over-stressed particle")
    c.at_least("topology.persist_frames", t.persist_frames, 1, "use at least one frame")
    c.positive("topology.band_width", t.band_width, "give the band half-width in Δx, e.g. band_width = 1.0")
    c.positive("topology.pair_radius", t.pair_radius, "give the pair radius in Δx, e.g. pair_radius = 1.5")
    c.within("topology.direction_agreement", t.direction_agreement, 0.0, 1.0, "use a |cos| threshold in [0, 1]")
    c.at_least("topology.max_events", t.max_events, 1, "allow at least one fracture event")
    c.at_least("topology.min_fragment_particles", t.min_fragment_particles, 1, "use a positive particle count")
    c.at_least("topology.cells", t.cells, 1, "shatter into at least one cell")
    c.positive("topology.impact_radius", t.impact_radius, "give the spread of the cells in metres, e.g. 0.1")
    for i, plane in enumerate(t.planes):
        p = f"topology.planes[{i}]"
        c.nonzero(f"{p}.normal", plane.normal, "give the plane normal, e.g. normal = [1, 0, 0]")
        c.at_least(f"{p}.latch_frame", plane.latch_frame, 0, "use a frame index >= 0")
        if plane.latch_time is None and plane.latch_frame > frames:  # a timed plane ignores its latch_frame
            c.fail(
                f"{p}.latch_frame",
                f"{p}.latch_frame = {plane.latch_frame} is after the last frame ({frames}), so the plane never cuts",
                "latch within the run or raise frames",
            )
        if plane.latch_time is not None:
            c.at_least(f"{p}.latch_time", plane.latch_time, 0.0, "use a time in seconds >= 0")


def _check_render(c: _Checker, r: RenderConfig) -> None:
    c.within("render.width", r.width, 2, MAX_IMAGE_SIDE, f"use an image width of 2 to {MAX_IMAGE_SIDE} pixels")
    c.within("render.height", r.height, 2, MAX_IMAGE_SIDE, f"use an image height of 2 to {MAX_IMAGE_SIDE} pixels")
    c.at_least("render.fps", r.fps, 1, "use a positive frame rate")
    c.within("render.fps", r.fps, 1, MAX_FPS, f"use a playback rate of 1 to {MAX_FPS} frames per second, e.g. fps = 24")
    if r.max_stretch is not None and not r.max_stretch > 1.0:
        c.fail(
            "render.max_stretch", f"render.max_stretch = {r.max_stretch!r} is not above 1", "use e.g. 1.25, or unset it"
        )
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
    cross = (
        view[1] * cam.up[2] - view[2] * cam.up[1],
        view[2] * cam.up[0] - view[0] * cam.up[2],
        view[0] * cam.up[1] - view[1] * cam.up[0],
    )
    if math.sqrt(sum(x * x for x in cross)) <= 1e-9 * math.sqrt(sum(x * x for x in view)) * math.sqrt(
        sum(x * x for x in cam.up)
    ):
        c.fail(
            "render.camera.up",
            f"render.camera.up = {list(cam.up)} is parallel to the viewing direction",
            "tilt the eye or choose another up vector",
        )
