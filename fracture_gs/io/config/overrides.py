"""Command-line overrides of a loaded config: --preset, --frames, --resolution, --variants.

Presets: `preset` is `small` (Δx = 1/64) or `paper` (Δx = 1/128). A file is taken literally;
`apply_overrides(cfg, preset=...)` (the CLI's `--preset`) switches an existing config to the
preset's Δx, rescales the explicit grid shape to cover the same box (64³ ↔ 128³) and rescales
`sim.dt` by the same ratio so the CFL number stays put. It is idempotent.
"""

from __future__ import annotations

import copy
import difflib
import re
from typing import Any, Mapping, Optional, Sequence, Union

from ...config import BUILTIN_SCENES, PRESETS, SceneConfig
from ...errors import ArgumentError, ConfigError
from ...variants import VARIANT_NAMES
from .build import set_key
from .validate import MAX_IMAGE_SIDE, validate


def parse_resolution(text: Union[str, Sequence[int]], source: str = "") -> tuple[int, int]:
    """`"640x480"` (or a (w, h) pair) → (640, 480); both at least 2 pixels."""
    if isinstance(text, str):
        parts = text.lower().replace("×", "x").split("x")
        if len(parts) != 2 or not all(re.fullmatch(r"[0-9]{1,6}", p.strip()) for p in parts):
            raise ConfigError(
                source,
                "--resolution",
                f"--resolution {text!r} is not WIDTHxHEIGHT; write it like --resolution 640x480.",
            )
        w, h = (int(p) for p in parts)
    else:
        pair = list(text) if isinstance(text, (list, tuple)) else None
        if pair is None or len(pair) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in pair):
            raise ConfigError(
                source,
                "--resolution",
                f"resolution {text!r} is not a (width, height) pair of whole numbers of pixels; pass e.g. (640, 480) "
                "or '640x480'.",
            )
        w, h = pair
    if w < 2 or h < 2:
        raise ConfigError(source, "--resolution", f"--resolution {w}x{h} is too small; use at least 2x2 pixels.")
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE:
        raise ConfigError(
            source,
            "--resolution",
            f"--resolution {w}x{h} is over {MAX_IMAGE_SIDE} pixels on a side; use a smaller image, e.g. 1920x1080.",
        )
    return w, h


def parse_variants(text: Union[str, Sequence[str]], source: str = "") -> list[str]:
    """`"baseline,full"` (or a list) → ['baseline', 'full'], each a known variant, no repeats."""
    names = [v.strip() for v in text.split(",")] if isinstance(text, str) else [str(v).strip() for v in text]
    if not any(names):
        raise ConfigError(source, "--variants", f"--variants is empty; list some of {', '.join(VARIANT_NAMES)}.")
    if "" in names:  # `full,` or `a,,b`: a name left out, or a stray comma; either way not what was meant
        raise ConfigError(
            source, "--variants", f"--variants {text!r} has an empty entry; write it like --variants baseline,full."
        )
    for v in names:
        if v not in VARIANT_NAMES:
            close = difflib.get_close_matches(v, VARIANT_NAMES, n=1)
            fix = f"did you mean {close[0]!r}?" if close else f"use names from {', '.join(VARIANT_NAMES)}."
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
    cfg.preset = preset  # type: ignore[assignment]  # checked against PRESETS above
    if abs(ratio - 1.0) < 1e-12:
        return
    if cfg.sim.grid == "explicit":
        nx, ny, nz = (max(4, int(round(n / ratio))) for n in cfg.sim.grid_shape)
        cfg.sim.grid_shape = (nx, ny, nz)
    cfg.sim.dx = new_dx
    cfg.sim.dt = cfg.sim.dt * ratio


def apply_overrides(
    cfg: SceneConfig,
    preset: Optional[str] = None,
    frames: Optional[int] = None,
    resolution: Union[str, Sequence[int], None] = None,
    variants: Union[str, Sequence[str], None] = None,
    source: str = "command line",
    keys: Optional[Mapping[str, Any]] = None,
) -> SceneConfig:
    """Return a validated copy of `cfg` with CLI overrides applied (None = keep).

    `preset="paper"` sets Δx = 1/128 (`"small"`: 1/64), rescales an explicit `grid_shape` to cover
    the same box (64³ → 128³) and `sim.dt` by the same ratio; `resolution` is `"WxH"` or (w, h);
    `variants` is `"a,b"` or a list; `keys` sets dotted TOML keys (`{"particles": 3000, "capture.load": "drop"}`)
    through the file reader's type checks (`build.set_key`), None values skipped. A bad flag raises ConfigError
    naming the flag or key; the result is validated again like a file, naming `source` (e.g.
    "configs/bread.toml with command-line overrides"), so a flag is held to the same ranges as its TOML key."""
    if not isinstance(cfg, SceneConfig):
        raise ArgumentError(
            f"apply_overrides: cfg must be a SceneConfig, got {type(cfg).__name__}; load one first, e.g. "
            "apply_overrides(fracture_gs.io.load_config('bread'), frames=30)."
        )
    out = copy.deepcopy(cfg)
    if preset is not None:
        _apply_preset(out, preset, "")
    if frames is not None:
        if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
            raise ConfigError(
                "", "--frames", f"--frames {frames!r} must be a positive integer; write it like --frames 30."
            )
        out.frames = frames
    if resolution is not None:
        out.render.width, out.render.height = parse_resolution(resolution)
        if out.scene not in BUILTIN_SCENES and out.capture.fit:
            out.capture.panel = "config"  # a fitted capture keeps the size asked for (the others take it as it is)
    if variants is not None:
        out.variants = parse_variants(variants)
    for dotted, value in (keys or {}).items():
        if value is not None:
            set_key(out, dotted, value, source)
    return validate(out, source)
