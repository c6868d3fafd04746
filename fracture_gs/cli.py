"""`fracture-gs` command line: render-sim, bench, figures, info, validate.

Every user error (bad config, bad PLY, missing file, bad flag) ends as one line
`fracture-gs: error: <sentence>` on stderr and exit code 2, never a traceback (set
FRACTURE_GS_DEBUG=1 to get the traceback instead). The heavy work lives
in modules imported only when a command needs them (`fracture_gs.runner`, `fracture_gs.bench` /
`apps.bench`, `fracture_gs.figures` / `apps.make_figures`), so `--help`, `info` and `validate` stay
fast and work on any machine.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import re
import sys
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

PROG = "fracture-gs"
REPO_ROOT = Path(__file__).resolve().parent.parent
DEVICE_RE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")


class CliError(Exception):
    """A user-facing error: its message is one sentence, printed without a traceback."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors become CliError (one line, exit 2)."""

    def error(self, message: str):  # type: ignore[override]
        raise CliError(f"{message} (see '{self.prog} --help')")


# --------------------------------------------------------------------------------------------
# parser


_MAIN_EPILOG = """\
examples:
  fracture-gs info                                  versions, GPU, renderer backend
  fracture-gs validate bread                        check a built-in or your own config
  fracture-gs render-sim bread                      simulate + render the default variants
  fracture-gs render-sim configs/recontact.toml --variants local_multifield,full
  fracture-gs render-sim my_scene.toml --preset paper --device cuda:0 --out runs/mine
  fracture-gs bench --device cuda:0                 transfer timings (paper Table 2)
  fracture-gs figures --out figures/out             every table and figure of the paper

A CONFIG is a path to a TOML file or a built-in name ({names}).
"""

_RENDER_EPILOG = """\
examples:
  fracture-gs render-sim bread
  fracture-gs render-sim bread --variants baseline,full --frames 20 --resolution 320x240
  fracture-gs render-sim configs/exp_table3_bread.toml --preset paper --device cuda:0
  fracture-gs render-sim my_scene.toml --out runs/my_scene

Writes one folder per variant (frames, metrics.jsonl, topology) and a side-by-side comparison
video under --out (default runs/<config name>). Ctrl-C keeps what was written so far.
"""

_BENCH_EPILOG = """\
examples:
  fracture-gs bench                                 Table 2 branches on the bread scene
  fracture-gs bench exp_table2_bread --preset paper --device cuda:0 --out runs/bench

Times the transfer branches of the paper's Table 2 on one particle set in one process (CUDA
events after warm-up, medians) and reports grid memory per branch. Meaningful on a GPU.
"""

_FIGURES_EPILOG = """\
examples:
  fracture-gs figures
  fracture-gs figures --device cuda:0 --out figures/out

Reruns every experiment config (exp_table*.toml) and writes the paper's tables and figures.
"""

_INFO_EPILOG = """\
examples:
  fracture-gs info

Reports Python, torch, Warp and gsplat versions, CUDA devices, which renderer `--device auto`
picks and why, and Warp's kernel cache directory. Nothing is compiled.
"""

_VALIDATE_EPILOG = """\
examples:
  fracture-gs validate bread
  fracture-gs validate configs/exp_table5_bread_vlm.toml --dump

Loads the config (following `extends`), checks every key and value, and prints a summary; exit
code 0 when valid, 2 with a one-sentence error otherwise. --dump prints the fully resolved TOML.
"""


def _add_common_run_flags(p: argparse.ArgumentParser, out_help: str) -> None:
    p.add_argument("--device", default="auto", metavar="DEVICE", help="auto (default: cuda:0 if available, else cpu), cpu, cuda or cuda:N")
    p.add_argument("--out", metavar="DIR", help=out_help)


def build_parser() -> argparse.ArgumentParser:
    """The full argparse tree (also used by the docs and tests)."""
    from .io.config import builtin_configs

    fmt = argparse.RawDescriptionHelpFormatter
    parser = _Parser(
        prog=PROG,
        description="Simulate 3D Gaussian Splatting scenes as MLS-MPM particles that fracture "
        "(FractureFields) and render comparison videos.",
        epilog=_MAIN_EPILOG.format(names=", ".join(builtin_configs())),
        formatter_class=fmt,
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("render-sim", help="simulate a scene and render side-by-side variant videos", formatter_class=fmt,
                       description="Simulate a scene config with several transfer variants and render comparison videos.",
                       epilog=_RENDER_EPILOG)
    p.add_argument("config", metavar="CONFIG_OR_SCENE", help="TOML path or built-in name (e.g. bread)")
    p.add_argument("--variants", metavar="A,B,C", help="comma-separated variants (default: the config's `variants`)")
    p.add_argument("--preset", metavar="small|paper", help="small (dx 1/64, CPU sized) or paper (dx 1/128, paper particle counts)")
    p.add_argument("--frames", metavar="N", type=_positive_int, help="number of frames (default: the config's)")
    p.add_argument("--particles", metavar="N", type=_positive_int,
                   help="built-in scenes only: override the preset's particle count (quick looks)")
    p.add_argument("--resolution", metavar="WxH", help="image size, e.g. 640x480 (default: the config's)")
    p.add_argument("--profile", action="store_true",
                   help="print where the wall time goes by phase (simulate, diagnostics, render, compose, encode, io); "
                        "also written to profile.md")
    _add_common_run_flags(p, "output folder (default: runs/<config name>)")

    p = sub.add_parser("bench", help="time the transfer branches (paper Table 2)", formatter_class=fmt,
                       description="Benchmark the transfer branches of the paper's Table 2: speed and grid memory.",
                       epilog=_BENCH_EPILOG)
    p.add_argument("config", metavar="CONFIG", nargs="?", default="exp_table2_bread", help="config to benchmark (default: exp_table2_bread)")
    p.add_argument("--variants", metavar="A,B,C", help="branches to time (default: the config's `variants`)")
    p.add_argument("--preset", metavar="small|paper", help="small or paper particle counts and grid")
    _add_common_run_flags(p, "output folder (default: runs/bench)")

    p = sub.add_parser("figures", help="regenerate every table and figure of the paper", formatter_class=fmt,
                       description="Rerun the paper's experiments and write its tables and figures.",
                       epilog=_FIGURES_EPILOG)
    _add_common_run_flags(p, "output folder (default: figures/out)")

    sub.add_parser("info", help="versions, GPU and renderer backend", formatter_class=fmt,
                   description="Show the software and hardware fracture-gs sees.", epilog=_INFO_EPILOG)

    p = sub.add_parser("validate", help="check a config and print a summary", formatter_class=fmt,
                       description="Load and check a config without simulating anything.", epilog=_VALIDATE_EPILOG)
    p.add_argument("config", metavar="CONFIG", help="TOML path or built-in name")
    p.add_argument("--dump", action="store_true", help="also print the fully resolved config as TOML")
    return parser


def _positive_int(text: str) -> int:
    """argparse type for --frames."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; write it like --frames 30") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


# --------------------------------------------------------------------------------------------
# devices and lazy imports


def _cuda_devices() -> tuple[bool, int, str]:
    """(available, count, reason) from torch, imported lazily; never touches gsplat."""
    try:
        import torch
    except Exception as exc:  # noqa: BLE001 - report, do not crash
        return False, 0, f"torch cannot be imported ({exc})"
    if not torch.cuda.is_available():
        build = "CPU-only torch build" if torch.version.cuda is None else "no CUDA device or driver"
        return False, 0, f"torch.cuda.is_available() is False ({build})"
    return True, torch.cuda.device_count(), "torch.cuda.is_available() is True"


def resolve_device(spec: str) -> str:
    """Check `auto|cpu|cuda[:N]` and resolve `auto`; a CUDA device must exist."""
    spec = (spec or "auto").strip().lower()
    if not DEVICE_RE.match(spec):
        raise CliError(f"--device {spec!r} is not a device; use auto, cpu, cuda or cuda:N (e.g. cuda:0).")
    if spec == "cpu":
        return "cpu"
    available, count, reason = _cuda_devices()
    if spec == "auto":
        return "cuda:0" if available else "cpu"
    if not available:
        raise CliError(f"--device {spec} was requested but CUDA is not available here ({reason}); use --device cpu or auto.")
    index = int(spec.split(":")[1]) if ":" in spec else 0
    if index >= count:
        raise CliError(f"--device {spec} does not exist; this machine has {count} CUDA device(s), cuda:0 to cuda:{count - 1}.")
    return f"cuda:{index}"


def _import_first(candidates: Sequence[tuple[str, str]], what: str) -> Callable:
    """Import the first available `module.attr`; a missing one is a one-sentence CliError."""
    problems = []
    for module, attr in candidates:
        if module.startswith("apps.") and (REPO_ROOT / "apps").is_dir() and str(REPO_ROOT) not in sys.path:
            sys.path.insert(0, str(REPO_ROOT))
        try:
            mod = importlib.import_module(module)
        except ImportError as exc:
            problems.append(f"{module}: {exc}")
            continue
        if hasattr(mod, attr):
            return getattr(mod, attr)
        problems.append(f"{module} has no {attr}()")
    raise CliError(f"{what} is not available in this installation ({'; '.join(problems)}); install the full fracture-gs package or run from a complete checkout.")


# --------------------------------------------------------------------------------------------
# commands


_PARTIAL_OUT: Optional[Path] = None
"""Output folder of the command in progress (reported on Ctrl-C)."""


def _print_summary(summary: Any) -> None:
    """Print a runner's summary dict as `key: value` lines (JSON for nested values)."""
    if not isinstance(summary, dict):
        if summary is not None:
            print(summary)
        return
    for key, value in summary.items():
        text = value if isinstance(value, (str, int, float)) else json.dumps(value, default=str)
        print(f"{key}: {text}")


def cmd_render_sim(args: argparse.Namespace) -> int:
    """render-sim: load, override, validate, then hand over to fracture_gs.runner."""
    global _PARTIAL_OUT
    from .io.config import apply_overrides, find_config, load_config

    path = find_config(args.config)
    cfg = load_config(path)
    device = resolve_device(args.device)
    cfg = apply_overrides(cfg, preset=args.preset, frames=args.frames, resolution=args.resolution, variants=args.variants,
                          source=f"{path} with command-line overrides")
    out_dir = Path(args.out) if args.out else Path("runs") / cfg.name
    run = _import_first([("fracture_gs.runner", "run_render_sim")], "render-sim (fracture_gs.runner.run_render_sim)")
    _PARTIAL_OUT = out_dir
    if getattr(args, "particles", None):
        cfg.particles = args.particles
    print(f"render-sim: {cfg.name} ({cfg.scene}, preset {cfg.preset}), {cfg.frames} frames, variants {', '.join(cfg.variants)}, device {device} -> {out_dir}")
    summary = run(cfg, list(cfg.variants), device, out_dir, profile=args.profile) or {}
    table = out_dir / "summary.md"
    print(table.read_text() if table.exists() else json.dumps(summary, indent=2, default=str))
    print(f"outputs in {out_dir}: comparison.mp4, one <variant>.mp4 each, frames/, metrics.jsonl, summary.json, topology.npz, config.toml")
    if summary.get("profile"):
        print(summary["profile"], end="")
    failed = [f"{v['variant']} {v['status']}" for v in summary.get("variants", []) if v.get("status", "ok") != "ok"]
    if failed:
        print(f"fracture-gs: error: {'; '.join(failed)}; every frame and metric written before that is in {out_dir}", file=sys.stderr)
        return 1
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """bench: time the Table 2 branches via fracture_gs.bench or apps.bench."""
    global _PARTIAL_OUT
    from .io.config import apply_overrides, find_config, load_config

    path = find_config(args.config)
    cfg = load_config(path)
    device = resolve_device(args.device)
    cfg = apply_overrides(cfg, preset=args.preset, variants=args.variants, source=f"{path} with command-line overrides")
    out_dir = Path(args.out) if args.out else Path("runs") / "bench"
    run = _import_first([("fracture_gs.bench", "run_bench"), ("apps.bench", "run_bench")], "bench (run_bench in fracture_gs.bench or apps/bench.py)")
    _PARTIAL_OUT = out_dir
    _print_summary(run(cfg, list(cfg.variants), device, out_dir))
    return 0


def cmd_figures(args: argparse.Namespace) -> int:
    """figures: regenerate tables and figures via fracture_gs.figures or apps.make_figures."""
    global _PARTIAL_OUT
    device = resolve_device(args.device)
    out_dir = Path(args.out) if args.out else Path("figures") / "out"
    run = _import_first([("fracture_gs.figures", "run_figures"), ("apps.make_figures", "run_figures")], "figures (run_figures in fracture_gs.figures or apps/make_figures.py)")
    _PARTIAL_OUT = out_dir
    _print_summary(run(device, out_dir))
    return 0


def _prepare_warp() -> None:
    """The CLI is an application, so it sets Warp up for the whole process: no per-module load
    lines (log level WARNING), and on a machine without a CUDA driver Warp's native start-up
    warning is kept off stderr so user errors stay one line (`fracture-gs info` reports devices).
    The library itself never does this (`fracture_gs.runtime`)."""
    import warp as wp

    from .runtime import ensure_warp

    wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    available, _, _ = _cuda_devices()
    if available:
        ensure_warp()
        return
    sys.stderr.flush()
    saved, devnull = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        ensure_warp()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def _version_of(module: str) -> tuple[Optional[Any], str]:
    """Import a module lazily: (module or None, version or the failure)."""
    try:
        mod = importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - info reports every failure
        return None, f"not importable ({type(exc).__name__}: {exc})"
    return mod, str(getattr(mod, "__version__", getattr(getattr(mod, "config", None), "version", "unknown")))


def _warp_cache_dir(wp: Any) -> str:
    """Warp's kernel cache directory, found the way warp.init() would, without initializing it."""
    configured = getattr(wp.config, "kernel_cache_dir", None)
    if configured:
        return str(configured)
    if os.environ.get("WARP_CACHE_PATH"):
        return os.path.realpath(os.environ["WARP_CACHE_PATH"]) + "  (WARP_CACHE_PATH)"
    try:
        from warp._src.build import appdirs  # private: only used to print the default location

        return appdirs.user_cache_dir(appname="warp", appauthor="NVIDIA", version=wp.config.version)
    except Exception:  # noqa: BLE001
        return "(default location; set WARP_CACHE_PATH to choose one)"


def _info_lines() -> list[tuple[str, str]]:
    """Rows of `fracture-gs info`."""
    from . import __version__

    rows = [("fracture-gs", f"{__version__}  ({Path(__file__).resolve().parent})"),
            ("python", f"{platform.python_version()}  ({sys.executable})"),
            ("platform", platform.platform())]
    torch, version = _version_of("torch")
    rows.append(("torch", version))
    available, count, reason = _cuda_devices()
    if torch is not None:
        rows.append(("cuda", f"{count} device(s), CUDA {torch.version.cuda}" if available else f"not available: {reason}"))
        for i in range(count):
            props = torch.cuda.get_device_properties(i)
            rows.append((f"  cuda:{i}", f"{props.name}, {props.total_memory / 2**30:.1f} GiB, sm_{props.major}{props.minor}"))
    wp, version = _version_of("warp")
    rows.append(("warp", version))
    if wp is not None:
        rows.append(("  kernel cache", _warp_cache_dir(wp)))
    _, version = _version_of("gsplat")
    rows.append(("gsplat", version))
    if available:
        rows.append(("renderer", f"auto -> gsplat rasterization on cuda:0 ({reason})"))
    else:
        rows.append(("renderer", f"auto -> torch reference rasterizer on cpu ({reason}; gsplat's CUDA code is never compiled here)"))
    rows.append(("device", f"--device auto -> {'cuda:0' if available else 'cpu'}"))
    return rows


def cmd_info(args: argparse.Namespace) -> int:
    """info: versions, CUDA devices, renderer choice, warp kernel cache."""
    for key, value in _info_lines():
        print(f"{key:<16}{value}")
    return 0


def _describe_boundary(b: Any) -> str:
    """One short phrase per boundary for `validate`."""
    from .config import CuboidBoundary, ParticleRegion, PlaneBoundary

    def v(t: Sequence[float]) -> str:
        return "(" + ", ".join(f"{x:g}" for x in t) + ")"

    if isinstance(b, PlaneBoundary):
        return f"plane {b.mode} through {v(b.point)} normal {v(b.normal)}"
    if isinstance(b, CuboidBoundary):
        return f"cuboid {v(b.lower)}-{v(b.upper)} velocity {v(b.velocity)}"
    if isinstance(b, ParticleRegion):
        what = f"delta_v {v(b.delta_v)}" if b.kind == "impulse" else f"velocity {v(b.velocity)}"
        return f"region {b.kind} {v(b.lower)}-{v(b.upper)} {what} t=[{b.start:g}, {b.end:g}]"
    return type(b).__name__


def _provider_summary(cfg: Any) -> str:
    t = cfg.topology
    if t.provider == "oracle":
        when = f"time {t.latch_time:g} s" if t.latch_time is not None else f"frame {t.latch_frame}"
        return f"oracle plane through {tuple(t.point)} normal {tuple(round(c, 4) for c in t.normal)}, latch at {when}, band {t.band_width:g} dx"
    if t.provider == "stress":
        return f"stress (sigma_R {cfg.material.sigma_R:g} Pa, min_particles {t.min_particles}, persist_frames {t.persist_frames}, band {t.band_width:g} dx)"
    return "none"


def cmd_validate(args: argparse.Namespace) -> int:
    """validate: load + check a config, print a summary (and optionally the resolved TOML)."""
    from .io.config import dump_config, find_config, load_config

    path = find_config(args.config)
    cfg = load_config(path)
    s, m = cfg.sim, cfg.material
    grid = f"explicit {'x'.join(map(str, s.grid_shape))}, dx {s.dx:g} m, origin {tuple(s.grid_origin)}" if s.grid == "explicit" else f"auto, dx {s.dx:g} m, margin {s.grid_margin:g}"
    rows = [("config", str(path)), ("scene", f"{cfg.scene} (name {cfg.name}, preset {cfg.preset})"),
            ("frames", f"{cfg.frames} x {cfg.frame_dt:g} s = {cfg.frames * cfg.frame_dt:g} s, substep {s.dt:g} s ({cfg.frame_dt / s.dt:.0f} per frame{', adaptive' if s.adaptive_dt else ''})"),
            ("variants", ", ".join(cfg.variants)), ("grid", grid), ("gravity", str(tuple(s.gravity))),
            ("material", f"{m.model} E {m.E:g} Pa, nu {m.nu:g}, density {m.density:g} kg/m3" + (f", {len(cfg.material_map)} material_map label(s)" if cfg.material_map else "")),
            ("boundaries", f"{len(s.boundaries)}" if s.boundaries else "none")]
    rows += [(f"  [{i}]", _describe_boundary(b)) for i, b in enumerate(s.boundaries)]
    rows += [("provider", _provider_summary(cfg)), ("render", f"{cfg.render.width}x{cfg.render.height} @ {cfg.render.fps} fps, backend {cfg.render.backend}")]
    for key, value in rows:
        print(f"{key:<12}{value}")
    print("ok: config is valid")
    if args.dump:
        print()
        print(dump_config(cfg, header=f"resolved from {path}"), end="")
    return 0


_WARP_COMMANDS = ("render-sim", "bench", "figures")
_COMMANDS = {"render-sim": cmd_render_sim, "bench": cmd_bench, "figures": cmd_figures, "info": cmd_info, "validate": cmd_validate}


# --------------------------------------------------------------------------------------------
# entry point


def _user_error_types() -> tuple[type, ...]:
    """Exceptions reported as one line: config, PLY (if io.ply exists), missing files, bad values."""
    from .io.config import ConfigError

    types: list[type] = [CliError, ConfigError, FileNotFoundError, ValueError]
    try:
        from .io.ply import PlyError

        types.append(PlyError)
    except Exception:  # noqa: BLE001 - io.ply may be absent or broken; its errors are then not ours
        pass
    return tuple(types)


def _one_line(exc: BaseException) -> str:
    """The error as one line (FileNotFoundError gets its path)."""
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"{exc.filename}: no such file or directory; check the path."
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Console entry point; returns the exit code (0 ok, 2 user error, 130 interrupted)."""
    global _PARTIAL_OUT
    _PARTIAL_OUT = None
    try:
        parser = build_parser()
        args = parser.parse_args(list(argv) if argv is not None else None)
        if not args.command:
            parser.print_help()
            return 0
        if args.command in _WARP_COMMANDS:
            _prepare_warp()
        return _COMMANDS[args.command](args)
    except SystemExit as exc:  # --help / --version: keep main() returning an exit code
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    except KeyboardInterrupt:
        where = f"partial outputs are in {_PARTIAL_OUT}" if _PARTIAL_OUT else "nothing was written"
        print(f"\n{PROG}: interrupted; {where}.", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - user errors become one line, bugs keep their traceback
        if not isinstance(exc, _user_error_types()) or os.environ.get("FRACTURE_GS_DEBUG"):
            raise
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
