"""A captured PLY → a simulated object, a static background and a config with every choice explicit.

`resolve(cfg)` reads the PLY, removes broken Gaussians, floaters and outliers, splits the region of
interest from the background, fits the object into the simulation domain (up axis, scale, centre),
fills its interior, places the load and the grid around it and points the camera at it. The
returned config holds the results as plain values (fit, ROI box, grid, boundaries, camera), so the
same run can be repeated from it, edited (`fracture-gs init` writes it with comments) and taken
back to the scene's frame (`SceneTransform.inverse`).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import torch

from .. import assets
from ..config import CameraConfig, RenderConfig, SceneConfig
from ..errors import SceneError
from ..io.gaussian_set import GaussianSet
from .camera import frame_box, trainer_view
from .clean import clean
from .fit import (
    auto_roi,
    check_view,
    config_rotation,
    detect_up,
    find_cameras_json,
    fit_transform,
    read_cameras,
    roi_mask,
)
from .ground import find_ground
from .loads import apply_load, auto_load, plan_load
from .materials import apply_material, apply_regions, substep_note
from .resolution import choose as choose_resolution
from .sample import sample
from .transform import SceneTransform

FILL_WARNING = 0.1
"""Below this fraction of the solid volume enclosed by the shell, the surface is probably open."""


@dataclass
class Capture:
    """A resolved captured scene."""

    cfg: SceneConfig
    gaussians: GaussianSet  # [N] the object in the simulation frame, interior fill included
    background: Optional[GaussianSet]  # static Gaussians outside the ROI (simulation frame), or None
    transform: Optional[SceneTransform]  # scene → simulation (None: the PLY was used as written)
    notes: list = field(default_factory=list)  # one line per automatic choice


def resolve(cfg: SceneConfig, device: str = "cpu") -> Capture:
    """See the module doc. `device` decides the resolution budget and the panel size. Raises SceneError (one
    sentence naming the file and the fix) for scenes that leave nothing to simulate."""
    from ..io.config import validate
    from ..io.devices import as_device
    from ..io.formats import read_gaussians

    device = str(as_device("resolve", device))  # "tpu" was taken for the CPU's budget without a word
    if not isinstance(cfg, SceneConfig):
        from ..errors import ArgumentError

        raise ArgumentError(
            f"resolve: cfg must be a SceneConfig, got {type(cfg).__name__}; load the scene's config first, e.g. "
            "resolve(fracture_gs.io.load_config('scene.ply'))."
        )
    if cfg.scene in assets.names():  # "bread: no such file; ... use a built-in scene: bread, ..." said nothing useful
        from ..errors import ArgumentError

        raise ArgumentError(
            f"resolve: scene = {cfg.scene!r} is a built-in scene, and resolve prepares captured scenes (a splat file) "
            "only; use fracture_gs.pipeline.prepare_scene(cfg) for either kind."
        )
    cfg = copy.deepcopy(cfg)
    path = Path(cfg.scene)
    validate(cfg, f"{path} (captured scene)")  # a config built in Python, not loaded, is checked here too
    if not path.is_file():
        raise SceneError(
            f"{path}: no such file; check the path (or use a built-in scene: {', '.join(assets.names())})."
        )
    cap = cfg.capture
    gs, unreadable, _ = read_gaussians(path)
    if not cap.fit:
        return _as_written(cfg, gs, unreadable)
    notes = []
    keep, report = clean(gs, cap.min_opacity, cap.outlier_neighbours, cap.outlier_std)
    report.total += unreadable
    report.broken += unreadable
    notes.append(report.line())
    if report.kept < 10:
        raise SceneError(
            f"{path}: only {report.kept} of {report.total} Gaussians are left after removing broken ones, faint "
            f"floaters (opacity < capture.min_opacity = {cap.min_opacity:g}) and outliers; lower capture.min_opacity "
            f"or raise capture.outlier_std."
        )
    kept = gs.subset(keep)
    Q = config_rotation(cap)
    cams_path = find_cameras_json(path, cap.cameras_json)
    needs_cameras = (cap.up == "auto" and Q is None) or cap.camera == "trainer"
    cameras = read_cameras(cams_path) if cams_path and needs_cameras else []
    if Q is None:
        up, up_note = detect_up(cap, cameras)
    else:
        up, up_note = Q[2].clone(), "up axis from capture.rotation"  # the scene axis the fit takes to +z
    above = _above_ground(kept.means, up, cap, notes)
    roi_note = "region of interest: automatic (robust bounds grown to what connects to them)"
    if cap.roi == "auto":  # resolved to a box, so the written config repeats it
        lo, hi = auto_roi(kept.means[above].to(torch.float64), cap.percentile, f"{path}: ")
        cap.roi, cap.roi_lower, cap.roi_upper = "box", _vec(lo), _vec(hi)
        inside, _ = roi_mask(kept.means, cap, str(path))
    else:
        inside, roi_note = roi_mask(kept.means, cap, str(path))
    inside &= above
    n_obj = int(inside.sum())
    if n_obj < 10:
        raise SceneError(
            f"{path}: the region of interest holds {n_obj} of {report.kept} Gaussians; move or widen capture.roi_* "
            f'(or set capture.roi = "auto").'
        )
    notes.append(f"{roi_note}: {n_obj} Gaussians simulated, {report.kept - n_obj} kept as a static background")
    obj, bg = kept.subset(inside), kept.subset(~inside)
    if cap.regions:
        notes.append(apply_regions(cfg, obj, f"{path}: "))
    fit = _fit(obj, up, up_note, Q, cap, path, notes)
    cap.scale, cap.rotation, cap.offset = fit.scale, fit.to_config()["rotation"], fit.to_config()["offset"]
    obj = fit.gaussians(obj)
    bg = fit.gaussians(bg) if len(bg) else None
    lo, hi = obj.means.min(0).values.double(), obj.means.max(0).values.double()
    notes.append(apply_material(cfg, cap.size))
    res = choose_resolution(obj, cap, device)
    dx, cap.cells_across = res.dx, res.cells
    notes.append(res.note)
    if cfg.fill_interior:
        obj = _fill(obj, cap, dx, notes, cap.max_particles or res.budget)
    obj, sample_note = sample(obj, 0.5 * dx)
    notes.append(sample_note)
    duration = cfg.frames * cfg.frame_dt
    if cfg.sim.boundaries and cap.load != "none":  # e.g. extends = "bread": its grips are the load
        plan = plan_load("none", lo, hi, dx, cap.size, 0.0, duration)
        plan.note = (
            f"load: the config's own {len(cfg.sim.boundaries)} boundaries (capture.load = {cap.load!r} not added)"
        )
    else:
        kind, why = auto_load(lo, hi, cap.ground_level is not None) if cap.load == "auto" else (cap.load, "")
        plan = plan_load(kind, lo, hi, dx, cap.size, cap.load_speed, duration)
        if why:
            plan.note = f"{plan.note} (capture.load = 'auto' chose {kind}: {why}; --load sets it)"
        replaced = _replaced_by_load(cfg, plan)
        apply_load(cfg, plan)
        if replaced:
            plan.note += f"; the config's {' and '.join(replaced)} {'is' if len(replaced) == 1 else 'are'} not used "
            plan.note += '(the load sets them: capture.load = "none" keeps the config\'s own)'
    notes.append(plan.note)
    cap.load, cap.load_speed = "none", 0.0  # written out as boundaries: a rerun must not add them again
    room_lo, room_hi = _room(cap.size, lo, hi, plan, duration)
    if cfg.sim.grid == "auto":
        _grid(cfg, room_lo, room_hi, dx)
        notes.append(f"grid {'×'.join(map(str, cfg.sim.grid_shape))} cells of {1e3 * dx:.3g} mm")
    notes.append(substep_note(cfg))
    if cap.panel == "auto":
        r = cfg.render
        written = (r.width, r.height)
        r.width, r.height = (1280, 720) if str(device).startswith("cuda") else (640, 480)
        if written not in AUTO_PANELS:  # a size the config asked for, not the placeholder of capture.toml
            notes.append(
                f'panel: {r.width}×{r.height} (capture.panel = "auto"); the [render] width × height the config '
                f'gives, {written[0]}×{written[1]}, is not used (capture.panel = "config" keeps it)'
            )
        cap.panel = "config"
    asked = _camera_asked(cfg.render.camera)
    _camera(cfg, cameras, fit, lo, hi, room_lo, room_hi, notes, cams_path)
    if asked and not notes[-1].startswith("camera: [render.camera] as written"):
        notes[-1] += (
            f"; the config's [render.camera] {', '.join(asked)} {'is' if len(asked) == 1 else 'are'} not used "
            '(capture.camera = "config" keeps them)'
        )
    cfg.sim.max_fragments = max(cfg.sim.max_fragments, 2 * cfg.topology.max_events + 2)
    return Capture(validate(cfg, f"{path} (captured scene)"), obj, bg, fit, notes)


def _replaced_by_load(cfg: SceneConfig, plan) -> list:
    """The config's initial_velocity and sim.gravity that a load with boundaries replaces by its own, as note
    text ("initial_velocity [0, 0, -5]"): a value the user wrote would otherwise vanish without a word."""
    if not plan.boundaries:
        return []
    pairs = (
        ("initial_velocity", cfg.initial_velocity, plan.initial_velocity),
        ("sim.gravity", cfg.sim.gravity, plan.gravity),
    )
    return [
        f"{k} {[float(v) for v in mine]}"
        for k, mine, theirs in pairs
        if tuple(map(float, mine)) != tuple(map(float, theirs)) and any(mine)
    ]


def _fit(obj: GaussianSet, up, up_note: str, Q, cap, path: Path, notes: list) -> SceneTransform:
    """The scene → simulation transform: capture.scale, rotation and offset as given (each alone or together),
    the rest automatic. A given scale decides the object's size: capture.size follows it, within its range."""
    offset = None if cap.offset is None else torch.tensor(cap.offset, dtype=torch.float64)
    fit = fit_transform(obj.means, up, cap.size, scale=cap.scale, rotation=Q, offset=offset, source=f"{path}: ")
    given = [k for k in ("scale", "rotation", "offset") if getattr(cap, k) is not None]
    if cap.scale is not None:
        q = obj.means.to(torch.float64) @ fit.rotation.T
        size = fit.scale * float((q.max(0).values - q.min(0).values).max())
        from ..io.config.validate import MAX_CAPTURE_SIZE, MIN_CAPTURE_SIZE

        if not MIN_CAPTURE_SIZE <= size <= MAX_CAPTURE_SIZE:
            raise SceneError(
                f"{path}: capture.scale = {cap.scale:g} makes the object's longest side {size:.4g} m, outside "
                f"{MIN_CAPTURE_SIZE:g} to {MAX_CAPTURE_SIZE:g} m; give a scale near "
                f"{cap.size * fit.scale / size:.4g} (capture.size over the longest side), or remove capture.scale."
            )
        if abs(size - cap.size) > 1e-6 * size:
            notes.append(f"capture.size {cap.size:g} m follows capture.scale: the longest side is {size:.4g} m")
            cap.size = size
    if not given:
        notes.append(f"{up_note}; scale {fit.scale:.4g} m per scene unit, longest side {cap.size:g} m")
    elif len(given) == 3:
        notes.append(f"fit from the config: scale {fit.scale:.4g} m per scene unit")
    else:
        auto = [k for k in ("scale", "rotation", "offset") if k not in given]
        notes.append(
            f"fit: {' and '.join(f'capture.{k}' for k in given)} from the config, {' and '.join(auto)} automatic "
            f"({up_note}); scale {fit.scale:.4g} m per scene unit, longest side {cap.size:g} m"
        )
    return fit


def _above_ground(means: torch.Tensor, up: torch.Tensor, cap, notes: list) -> torch.Tensor:  # -> [N] bool
    """Gaussians above the ground (`ground.find_ground`, or capture.ground_level as written); the rest is static
    background. Records the level found, so the written config repeats the run."""
    if cap.ground == "auto" and cap.ground_level is None:
        cap.ground_level = find_ground(means, up)
        if cap.ground_level is None:
            cap.ground = "none"
    if cap.ground_level is None:
        return torch.ones(len(means), dtype=torch.bool)
    above = means.to(torch.float64) @ (up.to(torch.float64) / up.norm()) > cap.ground_level
    if not bool(above.any()):
        raise SceneError(
            f"capture.ground_level = {cap.ground_level:g} lies above all {len(means)} Gaussians (along the up axis), "
            'so nothing is left to simulate; lower it, or remove it (capture.ground = "auto" finds the ground).'
        )
    notes.append(
        f"ground: a flat layer under the object ({int((~above).sum())} Gaussians up to {cap.ground_level:.4g} along "
        'the up axis) is kept as a static background and the floor stands on it (capture.ground = "none" keeps it)'
    )
    return above


AUTO_PANELS = ((640, 480), (1280, 720), (RenderConfig().width, RenderConfig().height))
"""The panel sizes capture.panel = "auto" chooses, and the unset default: a config holding one asked for none."""


def _camera_asked(camera) -> list:
    """The [render.camera] keys a config sets to other than their defaults (an automatic camera replaces them;
    orbit_degrees is kept)."""
    default = CameraConfig()
    return [k for k in ("eye", "target", "up", "fov_deg") if getattr(camera, k) != getattr(default, k)]


def _vec(t: torch.Tensor) -> tuple:
    return tuple(float(v) for v in t)


def _as_written(cfg: SceneConfig, gs: GaussianSet, unreadable: int = 0) -> Capture:
    """capture.fit = false: the PLY's coordinates are metres in the simulation frame (e.g. a PLY this
    package exported); only the interior fill applies."""
    notes = ["capture.fit = false: coordinates used as written"]
    if unreadable:
        notes.append(f"dropped {unreadable} unreadable Gaussians (NaN/inf, degenerate scales or zero rotations)")
    if cfg.fill_interior and not bool(gs.interior.any()):
        stats = {}
        gs = assets.fill_interior(gs, stats=stats)
        notes.append(f"filled {stats['added']} interior particles")
    return Capture(cfg, gs, None, None, notes)


def _fill(obj: GaussianSet, cap, dx: float, notes: list, budget: int) -> GaussianSet:
    """Fill at spacing Δx/2 (8 particles a cell); where the shell leaks at that resolution (a sparse
    capture), again at Δx and 2Δx, where its Gaussians close up: the first whose shell encloses empty
    space (at least a quarter of the solid volume), else the one that enclosed most if that is a closed
    surface (≥ FILL_WARNING), else (an open surface at every spacing) the finest. Fill particles are drawn
    (once a crack exposes them) with σ ≤ Δx/4, however coarse their spacing: crack faces stay crisp."""
    best, finest = None, None
    for spacing in (dx / 2, dx, 2 * dx):
        stats = {}
        filled = assets.fill_interior(
            obj,
            spacing=spacing,
            max_particles=budget,
            threshold=cap.fill_threshold,
            min_opacity=cap.min_opacity,
            closing=cap.fill_closing,
            stats=stats,
            seal_bottom=cap.seal_bottom,
        )
        finest = finest or (filled, stats)
        if best is None or stats["enclosed_fraction"] > best[1]["enclosed_fraction"]:
            best = (filled, stats)
        if stats["enclosed_fraction"] >= 0.25:
            break
    filled, stats = best if best[1]["enclosed_fraction"] >= FILL_WARNING else finest
    inner = filled.interior
    filled.scales[inner] = filled.scales[inner].clamp_max(0.25 * dx)
    enclosed, spacing = stats["enclosed_fraction"], 1e3 * (stats["spacing"] or 0)
    if enclosed < FILL_WARNING:
        notes.append(
            f"interior: the surface is open at {spacing:.3g} mm voxels (it encloses {100 * enclosed:.0f} % of the "
            f"solid it bounds), so the object is simulated as a shell as thick as its Gaussians ({stats['added']} "
            f"particles added inside that shell); to fill it as a solid, raise capture.fill_closing (now "
            f"{cap.fill_closing}) or lower capture.fill_threshold (now {cap.fill_threshold:g})"
        )
    else:
        notes.append(
            f"interior: filled with {stats['added']} particles at {spacing:.3g} mm spacing (the surface encloses "
            f"{100 * enclosed:.0f} % of the solid it bounds)"
        )
    return filled


def _room(size: float, lo, hi, plan, duration: float):
    """The box the run needs (simulation frame): the object, where the load moves it, and a margin."""
    pad = 0.1 * size
    room_lo, room_hi = lo - pad, hi + pad
    travel = (
        min(0.5 * size, max(abs(v) for b in plan.boundaries for v in _speeds(b)) * duration) if plan.boundaries else 0
    )
    room_lo[0], room_hi[0] = room_lo[0] - travel, room_hi[0] + travel
    if plan.floor is not None:
        room_lo[2] = min(float(room_lo[2]), plan.floor - 0.05 * size)
        room_lo[:2] -= 0.2 * size  # pieces spread on the floor
        room_hi[:2] += 0.2 * size
    if plan.room is not None:  # the load's own bodies (a ball's path, a plate above the object)
        room_lo = torch.minimum(room_lo, torch.tensor(plan.room[0], dtype=room_lo.dtype) - pad)
        room_hi = torch.maximum(room_hi, torch.tensor(plan.room[1], dtype=room_hi.dtype) + pad)
    return room_lo, room_hi


def _speeds(b) -> tuple:
    return tuple(getattr(b, "velocity", (0.0,))) + tuple(getattr(b, "delta_v", (0.0,)))


def _grid(cfg: SceneConfig, lo, hi, dx: float) -> None:
    w = cfg.sim.wall_cells
    origin = [math.floor(float(v) / dx) * dx - w * dx for v in lo]
    shape = [int(math.ceil((float(h) - o) / dx)) + w + 1 for o, h in zip(origin, hi)]
    cfg.sim.grid, cfg.sim.dx, cfg.sim.grid_origin, cfg.sim.grid_shape = "explicit", dx, tuple(origin), tuple(shape)


def _camera(cfg, cameras, fit, lo, hi, room_lo, room_hi, notes, cams_path=None) -> None:
    cap, r = cfg.capture, cfg.render
    if cap.camera == "trainer":
        if not cameras:
            raise SceneError(
                f'{cfg.scene}: capture.camera = "trainer" but no cameras.json was found beside the PLY; set '
                f'capture.cameras_json or use capture.camera = "auto".'
            )
        if not 0 <= cap.view < len(cameras):
            raise SceneError(
                f"{cfg.scene}: capture.view = {cap.view} but cameras.json has views 0..{len(cameras) - 1}."
            )
        cam = cameras[cap.view]
        check_view(cams_path, cap.view, cam)
        r.height = max(16, int(round(r.width * cam.height / cam.width / 2)) * 2)
        orbit = r.camera.orbit_degrees  # the view's pose replaces eye, target, up and fov; an asked orbit turns it
        r.camera = trainer_view(cam, fit, 0.5 * (lo + hi))
        r.camera.orbit_degrees = orbit
        notes.append(f"camera: trainer view {cap.view} ({cam.name or 'unnamed'})")
    elif cap.camera == "auto":
        frame_lo, frame_hi = lo.clone(), hi.clone()
        frame_lo[0], frame_hi[0] = 0.5 * (lo[0] + room_lo[0]), 0.5 * (hi[0] + room_hi[0])
        frame_lo[2] = min(float(lo[2]), float(room_lo[2]) + 0.05 * cap.size)
        orbit = r.camera.orbit_degrees
        r.camera = frame_box(frame_lo, frame_hi, r.width, r.height)
        r.camera.orbit_degrees = orbit
        notes.append("camera: frames the object from the front, 20° above")
    else:
        notes.append("camera: [render.camera] as written")
    cap.camera = "config"
