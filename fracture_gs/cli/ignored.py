"""Flags that would do nothing in the combination given, refused before any work starts.

A flag the run would silently drop (--particles on a captured scene, --load on a built-in one, --schedule
beside --devices, bench's Table 2 sizes with --accuracy, ...) is a user error: whoever typed it believes it
changed the run. Each rule raises CliError with one sentence naming the flag, why it has no effect here and
what to do instead (exit 2, like any bad flag). The rules read the loaded config and the parsed flags only,
so they run in milliseconds, before a scene is built or a kernel compiled. Flags whose argparse default is
None are told apart from flags not typed by that None (`_given`).
"""

from __future__ import annotations

import argparse
from typing import Optional

from . import CliError
from .devices import resolve_device

_TABLE2_FLAGS = ("particles", "steps", "warmup", "trials", "placements", "grid", "no_graph", "sort")
_ACCURACY_FLAGS = ("quick", "cases", "from_json")
_FIGURES_RUN_FLAGS = ("protocol", "only", "reuse", "backend", "device")


def _given(args: argparse.Namespace, name: str) -> bool:
    """Whether the flag `name` (its argparse dest) was typed: its value is not the None / False default."""
    value = getattr(args, name, None)
    return value is not None and value is not False


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def run_devices(args: argparse.Namespace) -> tuple[str, Optional[list[str]]]:
    """render-sim's (device, devices): --devices resolved, every entry a distinct device, never beside --device."""
    if not _given(args, "devices"):
        return resolve_device(args.device), None
    text = args.devices
    names = [d.strip() for d in text.split(",")]
    if not any(names):
        raise CliError(f"--devices {text!r} names no device; write it like --devices cuda:0,cuda:1.")
    if not all(names):
        raise CliError(f"--devices {text!r} has an empty entry; write it like --devices cuda:0,cuda:1.")
    if _given(args, "device"):
        raise CliError(
            f"--device {args.device} has no effect beside --devices {text} (the first of --devices runs in this "
            "process); drop --device."
        )
    devices = [resolve_device(d) for d in names]
    for j, d in enumerate(devices):
        if d in devices[:j]:
            i = devices.index(d)
            alias = f" ({names[i]} and {names[j]} are both {d} here)" if names[i].lower() != names[j].lower() else ""
            raise CliError(
                f"--devices {text} names {d} twice{alias}; each device runs its own share of the variants, so list "
                "each device once (on one device, --schedule threads runs the variants at once)."
            )
    return devices[0], devices


def refuse_scene_flags(cfg, args: argparse.Namespace) -> None:
    """render-sim: flags that the config's kind of scene would make do nothing (capture flags on a built-in scene,
    built-in flags on a capture). Run on the config as loaded, before the flags are applied to it, so the
    sentence names the flag typed rather than the config key it would set."""
    from ..config import BUILTIN_SCENES

    if cfg.scene in BUILTIN_SCENES:
        _builtin_scene(cfg, args)
    else:
        _captured_scene(cfg, args)


def refuse_render_sim(cfg, args: argparse.Namespace, devices: Optional[list[str]]) -> None:
    """render-sim: flags that the config's scene, frame count, variants or devices would make do nothing."""
    refuse_scene_flags(cfg, args)
    every = getattr(args, "export_ply", None)
    if every is not None and every > cfg.frames:
        raise CliError(
            f"--export-ply {every} is beyond the last frame of this run ({cfg.frames}), so only frame 0 would be "
            f"written; use --export-ply N with N at most {cfg.frames} (or raise --frames)."
        )
    variants = list(cfg.variants)
    if devices and len(devices) > 1:
        if _given(args, "schedule"):
            raise CliError(
                f"--schedule {args.schedule} has no effect with --devices {args.devices}: the variants already run "
                "side by side, one device each; drop --schedule (it chooses how variants share one device)."
            )
        if len(devices) > len(variants):
            raise CliError(
                f"--devices {args.devices} names {len(devices)} devices for {len(variants)} variant(s) "
                f"({', '.join(variants)}), so {len(devices) - len(variants)} would sit idle; list at most "
                f"{len(variants)} device(s) or more --variants."
            )
    elif getattr(args, "schedule", None) in ("threads", "processes") and len(variants) < 2:
        each = "a thread" if args.schedule == "threads" else "a process"
        raise CliError(
            f"--schedule {args.schedule} runs the variants at once, {each} each, but this run has one variant "
            f"({variants[0]}); drop --schedule or list more --variants."
        )


def _builtin_scene(cfg, args: argparse.Namespace) -> None:
    """--load, --material and --quality set up a captured scene; a built-in scene has its own."""
    instead = {
        "load": "a built-in scene's load is its config's sim.boundaries",
        "material": "set [material] in a TOML config to change a built-in scene's material",
        "quality": "--preset sets a built-in scene's resolution",
    }
    for name, hint in instead.items():
        if _given(args, name):
            raise CliError(
                f"--{name} applies to captured scenes (a .ply, .splat or .spz file) only, and {cfg.name} simulates "
                f"the built-in scene {cfg.scene!r}; drop --{name} ({hint})."
            )


def _captured_scene(cfg, args: argparse.Namespace) -> None:
    """--particles and --preset size a built-in scene; --load, --material and --quality need the capture's fit."""
    if _given(args, "particles"):
        raise CliError(
            f"--particles sets a built-in scene's particle count, and {cfg.name} is a captured scene, whose particles "
            "are its Gaussians and their interior fill; drop --particles (--quality sets how finely it is filled)."
        )
    cap = cfg.capture
    if not cap.fit:
        for name in ("load", "material", "quality"):
            if _given(args, name):
                raise CliError(
                    f"--{name} has no effect on {cfg.name}: its capture.fit = false uses the scene as written (no "
                    f"fit, load, material preset or resolution choice); set capture.fit = true in the config or drop "
                    f"--{name}."
                )
        return
    if _given(args, "preset"):
        raise CliError(
            f"--preset sets a built-in scene's Δx, and {cfg.name} is a captured scene, whose Δx follows from "
            "--quality (capture.quality, or capture.cells_across); use --quality instead of --preset."
        )
    if _given(args, "quality") and cap.cells_across is not None:
        raise CliError(
            f"--quality has no effect on {cfg.name}: its capture.cells_across = {cap.cells_across} fixes the "
            "resolution; remove cells_across from the config or drop --quality."
        )
    if _given(args, "load") and cfg.sim.boundaries:
        raise CliError(
            f"--load has no effect on {cfg.name}: its {len(cfg.sim.boundaries)} sim.boundaries are its load (a run's "
            "config.toml keeps the load it chose that way); run the scene file itself with --load, or remove the "
            "boundaries from the config."
        )


def refuse_bench(args: argparse.Namespace, device: Optional[str]) -> None:
    """bench: Table 2's flags with --accuracy, the sweep's without it, what --from-json would not use.
    `device` is the resolved device (None with --from-json, which uses none)."""
    if not args.accuracy:
        for name in _ACCURACY_FLAGS:
            if _given(args, name):
                raise CliError(
                    f"{_flag(name)} applies to the speed-against-error sweep only; add --accuracy or drop "
                    f"{_flag(name)}."
                )
        if args.no_graph and device == "cpu":
            raise CliError(
                "--no-graph has no effect on the CPU (CUDA graphs exist on CUDA devices only); drop --no-graph or "
                "use --device cuda."
            )
        return
    for name in _TABLE2_FLAGS:
        if _given(args, name):
            raise CliError(
                f"{_flag(name)} sets up Table 2's timings and has no effect with --accuracy (the sweep sizes its own "
                f"cases); drop {_flag(name)} or --accuracy."
            )
    if _given(args, "from_json"):
        for name in ("quick", "cases", "device"):
            if _given(args, name):
                raise CliError(
                    f"{_flag(name)} has no effect with --from-json, which only redraws the table and plot of a saved "
                    f"sweep; drop {_flag(name)} or --from-json."
                )


def refuse_figures(args: argparse.Namespace) -> None:
    """figures --readme-only rewrites README.md from the folder: the flags of a rerun do nothing."""
    if not args.readme_only:
        return
    for name in _FIGURES_RUN_FLAGS:
        if _given(args, name):
            raise CliError(
                f"{_flag(name)} has no effect with --readme-only, which only rewrites OUT/README.md from what OUT "
                f"holds; drop {_flag(name)} or --readme-only."
            )


def refuse_repeated(parser: argparse.ArgumentParser, argv: list) -> None:
    """A flag given twice with different effects (`--device cpu --device cuda`, `--frames-png --no-frames-png`):
    argparse keeps the last, so the first would do nothing. The same flag with the same value twice is harmless
    and passes. Abbreviations count as the flag they abbreviate (argparse has already refused ambiguous ones)."""
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    command = next((t for t in argv if sub is not None and t in sub.choices), None)
    p = sub.choices[command] if command is not None else parser
    longs = [o for a in p._actions for o in a.option_strings if o.startswith("--")]
    seen: dict = {}
    i = 0
    while i < len(argv):
        token = argv[i]
        if token == "--":
            break
        name, eq, value = token.partition("=")
        if not name.startswith("--"):
            i += 1
            continue
        matches = [name] if name in longs else [o for o in longs if o.startswith(name)]
        action = p._option_string_actions.get(matches[0]) if len(matches) == 1 else None
        if action is None:
            i += 1
            continue
        takes_value = action.nargs != 0 and not isinstance(action, argparse.BooleanOptionalAction)
        if takes_value and not eq:
            value = argv[i + 1] if i + 1 < len(argv) else ""
            i += 1
        said = f"{matches[0]} {value}".strip() if takes_value else matches[0]
        before = seen.setdefault(action.dest, said)
        if before != said:
            raise CliError(
                f"{said} and {before} both set {action.option_strings[0]}, and only the last one typed would count; "
                "give it once."
            )
        i += 1
