"""Scene configs: TOML files ⇄ the dataclasses of `fracture_gs.config`.

Modules: `files` (find, read, `extends`), `build` (dicts → dataclasses), `validate` (values),
`dump` (dataclasses → TOML), `overrides` (command-line flags and presets).

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
    point = [0.0, 0.0, 0.1]    #   "sphere" → SphereBoundary, "region" → ParticleRegion
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

from ...config import BOUNDARY_TYPES, BUILTIN_SCENES, PRESETS, PROVIDERS
from ...errors import ConfigError
from .dump import config_to_dict, dump_config
from .files import CONFIG_DIR, builtin_configs, config_from_dict, find_config, load_config
from .overrides import apply_overrides, parse_resolution, parse_variants
from .validate import validate

__all__ = [
    "BOUNDARY_TYPES",
    "BUILTIN_SCENES",
    "CONFIG_DIR",
    "ConfigError",
    "PRESETS",
    "PROVIDERS",
    "apply_overrides",
    "builtin_configs",
    "config_from_dict",
    "config_to_dict",
    "dump_config",
    "find_config",
    "load_config",
    "parse_resolution",
    "parse_variants",
    "validate",
]
