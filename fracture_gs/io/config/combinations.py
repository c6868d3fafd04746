"""Config keys that the rest of the config makes do nothing (issue 34, bad input round four).

A key whose value the run would silently drop is refused like a bad value: whoever wrote it believes it changed
the run. Only a value other than the field's default can be told apart from a key not written, so the rules
compare with the dataclass defaults (`CaptureConfig()`), never with where a value came from (`extends`
chains merge before these checks). The rules read the built config only and raise through the checker of
`validate.py` (one sentence naming the key and the fix).
"""

from __future__ import annotations

import dataclasses
import math

from ...config import BUILTIN_SCENES, CaptureConfig

UP_AXES = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}
"""capture.up → the scene axis it names (`capture.fit` takes it from here: io does not import capture)."""
UP_AGREEMENT = 0.999
"""cos of the largest angle (≈ 2.6°) between capture.up and the axis capture.rotation takes to +z that counts as the
same axis (a rotation written to four digits passes)."""
_FIT_KEYS = ("scale", "rotation", "offset")  # refused with their own sentence by validate._check_fit
_WRITTEN_BY_RUNS = ("panel",)
"""Keys a run's config.toml holds away from the default on any scene: `--resolution` set capture.panel = "config"
on built-in scenes and fit = false captures too before round four, and such a file must load again."""


def changed_capture_keys(cap) -> list[str]:
    """The [capture] keys whose value differs from CaptureConfig's default, in field order (capture.panel, which
    runs wrote on every scene, left out)."""
    default = CaptureConfig()
    return [
        f.name
        for f in dataclasses.fields(cap)
        if f.name not in _WRITTEN_BY_RUNS and getattr(cap, f.name) != getattr(default, f.name)
    ]


def check_combinations(c, cfg) -> None:
    """Every rule of the module doc, in the order a reader meets the keys."""
    builtin = cfg.scene in BUILTIN_SCENES
    if builtin:
        _builtin_scene(c, cfg)
    else:
        _captured_scene(c, cfg)
    cap = cfg.capture
    if not builtin and cap.fit:
        _capture_keys(c, cfg, cap)


def _builtin_scene(c, cfg) -> None:
    """A built-in scene has no [capture] step and no PLY properties."""
    changed = changed_capture_keys(cfg.capture)
    if changed:
        key = changed[0]
        c.fail(
            f"capture.{key}",
            f"capture.{key} = {_show(getattr(cfg.capture, key))} has no effect: scene = {cfg.scene!r} is a built-in "
            "scene, and [capture] prepares captured scenes (a .ply, .splat or .spz file) only",
            f"remove capture.{key}, or set scene to a splat file",
        )
    if cfg.material_property is not None:
        c.fail(
            "material_property",
            f"material_property = {cfg.material_property!r} has no effect: scene = {cfg.scene!r} is a built-in scene "
            "with its own labels, and the key names a vertex property of a PLY",
            "remove material_property (set per-label materials with [[material_map]]), or set scene to a PLY",
        )


def _captured_scene(c, cfg) -> None:
    """`particles` sizes a built-in asset; `preset` sets a built-in scene's Δx (a capture's follows from
    capture.quality or capture.cells_across), unless capture.fit = false keeps the file's metres."""
    if cfg.particles is not None:
        c.fail(
            "particles",
            f"particles = {cfg.particles} has no effect: the scene is a captured scene, whose particles are its "
            "Gaussians and their interior fill",
            "remove particles (capture.quality or capture.max_particles set how finely it is filled)",
        )
    if cfg.preset != "small" and cfg.capture.fit:
        c.fail(
            "preset",
            f"preset = {cfg.preset!r} has no effect: a captured scene's Δx follows from capture.quality (or "
            "capture.cells_across)",
            'remove preset, and set capture.quality = "fine" or capture.cells_across instead',
        )
    if not cfg.capture.fit:
        changed = [k for k in changed_capture_keys(cfg.capture) if k not in ("fit", *_FIT_KEYS)]
        if changed:
            key = changed[0]
            c.fail(
                f"capture.{key}",
                f"capture.{key} = {_show(getattr(cfg.capture, key))} has no effect: capture.fit = false uses the "
                "scene as written (no clean-up, fit, resolution choice, load, material preset or camera)",
                f"set capture.fit = true to use it, or remove capture.{key}",
            )


def _capture_keys(c, cfg, cap) -> None:
    """[capture] keys that another [capture] key turns off."""
    default = CaptureConfig()
    if not cfg.fill_interior and cap.max_particles is not None:
        c.fail(
            "capture.max_particles",
            f"capture.max_particles = {cap.max_particles} has no effect: fill_interior = false adds no interior "
            "particles",
            "set fill_interior = true to fill the object, or remove capture.max_particles",
        )
    if cap.outlier_neighbours == 0 and cap.outlier_std != default.outlier_std:
        c.fail(
            "capture.outlier_std",
            f"capture.outlier_std = {cap.outlier_std:g} has no effect: capture.outlier_neighbours = 0 turns the "
            "outlier removal off",
            "give outlier_neighbours (e.g. 8) to use it, or remove capture.outlier_std",
        )
    if cap.roi in ("sphere", "all") and cap.percentile != default.percentile:
        c.fail(
            "capture.percentile",
            f"capture.percentile = {cap.percentile:g} has no effect: it bounds the automatic region of interest, and "
            f"capture.roi = {cap.roi!r}",
            'set capture.roi = "auto" to use it, or remove capture.percentile',
        )
    if cap.up != "auto" and cap.rotation is not None:
        axis = UP_AXES[cap.up]
        row = cap.rotation[2]  # the scene axis the rotation takes to +z, the simulation's up
        norm = math.sqrt(sum(v * v for v in row)) or 1.0
        if sum(a * v for a, v in zip(axis, row)) / norm < UP_AGREEMENT:
            c.fail(
                "capture.up",
                f"capture.up = {cap.up!r} has no effect: capture.rotation takes the scene axis "
                f"{[round(v, 4) for v in row]} to +z (up), not {cap.up}",
                "remove capture.up (capture.rotation decides the up axis), or remove capture.rotation",
            )


def _show(value) -> str:
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, (int, float)) for v in value):
            return str(list(value))
        return f"[{len(value)} entr{'y' if len(value) == 1 else 'ies'}]"
    return str(value)
