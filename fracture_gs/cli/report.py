"""The commands that only report: info (software and hardware) and validate (a config's summary)."""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path
from typing import Any, Sequence

from .. import bytecode
from . import CliError, hardware


def _info_lines() -> list[tuple[str, str]]:
    """Rows of `fracture-gs info`: nothing here imports torch, Warp or gsplat (`hardware`)."""
    from .. import __version__

    rows = [
        ("fracture-gs", f"{__version__}  ({Path(__file__).resolve().parent})"),
        ("python", f"{platform.python_version()}  ({sys.executable})"),
        ("platform", platform.platform()),
        ("torch", hardware.version("torch")),
    ]
    available, reason, found = hardware.cuda_status()
    rows.append(("cuda", reason if available else f"not available: {reason}"))
    rows += [(f"  cuda:{i}", f"{name}, {gib:.1f} GiB, {sm}") for i, (name, gib, sm) in enumerate(found)]
    rows.append(("warp", hardware.version("warp-lang")))
    rows.append(("  kernel cache", hardware.warp_cache_dir()))
    rows.append(("gsplat", hardware.version("gsplat")))
    if available:
        rows.append(("renderer", f"auto -> gsplat rasterization on cuda:0 ({reason})"))
    else:
        rows.append(
            (
                "renderer",
                f"auto -> Warp rasterizer on cpu ({reason}; gsplat's CUDA code is never compiled here)",
            )
        )
    rows.append(("device", f"--device auto -> {'cuda:0' if available else 'cpu'}"))
    rows.append(("video", _video_encoder()))
    rows.append(("bytecode", bytecode.info_line(bytecode.survey())))
    return rows


def _video_encoder() -> str:
    """The MP4 encoder render-sim will use, or the sentence it would stop with."""
    from ..errors import OutputError
    from ..io.video import ffmpeg

    try:
        exe = ffmpeg().get_ffmpeg_exe()
    except OutputError as exc:
        return f"unavailable: {exc}"
    return f"imageio-ffmpeg {hardware.version('imageio-ffmpeg')}, ffmpeg {exe}"


def cmd_info(args: argparse.Namespace) -> int:
    """info: versions, CUDA devices, renderer choice, warp kernel cache; with --warm-up, then every kernel
    compiled once on --device (`warm_up`, which imports torch and Warp: plain `info` imports neither)."""
    device = None
    if getattr(args, "warm_up", False):
        from .devices import resolve_device

        device = resolve_device(args.device)  # a bad device is one line before anything is printed
    elif getattr(args, "device", None) is not None:
        raise CliError(f"--device {args.device} only says where `info --warm-up` compiles; add --warm-up or drop it.")
    for key, value in _info_lines():
        print(f"{key:<16}{value}")
    if device is None:
        return 0
    from .warm_up import cmd_warm_up

    return cmd_warm_up(device)


def _describe_boundary(b: Any) -> str:
    """One short phrase per boundary for `validate`."""
    from ..config import CuboidBoundary, ParticleRegion, PlaneBoundary, SphereBoundary

    def v(t: Sequence[float]) -> str:
        return "(" + ", ".join(f"{x:g}" for x in t) + ")"

    if isinstance(b, PlaneBoundary):
        return f"plane {b.mode} through {v(b.point)} normal {v(b.normal)}"
    if isinstance(b, CuboidBoundary):
        pusher = f" pushing {v(b.push)}" if any(b.push) else ""
        return f"cuboid {v(b.lower)}-{v(b.upper)} velocity {v(b.velocity)}{pusher}"
    if isinstance(b, SphereBoundary):
        return f"sphere r={b.radius:g} at {v(b.center)} velocity {v(b.velocity)} t=[{b.start:g}, {b.end:g}]"
    if isinstance(b, ParticleRegion):
        what = f"delta_v {v(b.delta_v)}" if b.kind == "impulse" else f"velocity {v(b.velocity)}"
        return f"region {b.kind} {v(b.lower)}-{v(b.upper)} {what} t=[{b.start:g}, {b.end:g}]"
    return type(b).__name__


def _provider_summary(cfg: Any) -> str:
    t = cfg.topology
    if t.provider == "oracle":
        when = f"time {t.latch_time:g} s" if t.latch_time is not None else f"frame {t.latch_frame}"
        normal = tuple(round(c, 4) for c in t.normal)
        return f"oracle plane through {tuple(t.point)} normal {normal}, latch at {when}, band {t.band_width:g} dx"
    if t.provider == "stress":
        return (
            f"stress (sigma_R {cfg.material.sigma_R:g} Pa, min_particles {t.min_particles}, "
            f"persist_frames {t.persist_frames}, band {t.band_width:g} dx)"
        )
    return "none"


def cmd_validate(args: argparse.Namespace) -> int:
    """validate: load + check a config, print a summary (and optionally the resolved TOML)."""
    from ..io.config import dump_config, find_config, load_config

    path = find_config(args.config)
    cfg = load_config(path)
    s, m = cfg.sim, cfg.material
    grid = (
        f"explicit {'x'.join(map(str, s.grid_shape))}, dx {s.dx:g} m, origin {tuple(s.grid_origin)}"
        if s.grid == "explicit"
        else f"auto, dx {s.dx:g} m, margin {s.grid_margin:g}"
    )
    rows = [
        ("config", str(path)),
        ("scene", f"{cfg.scene} (name {cfg.name}, preset {cfg.preset})"),
        (
            "frames",
            f"{cfg.frames} x {cfg.frame_dt:g} s = {cfg.frames * cfg.frame_dt:g} s, substep {s.dt:g} s "
            f"({cfg.frame_dt / s.dt:.0f} per frame{', adaptive' if s.adaptive_dt else ''})",
        ),
        ("variants", ", ".join(cfg.variants)),
        ("grid", grid),
        ("gravity", str(tuple(s.gravity))),
        (
            "material",
            f"{m.model} E {m.E:g} Pa, nu {m.nu:g}, density {m.density:g} kg/m3"
            + (f", {len(cfg.material_map)} material_map label(s)" if cfg.material_map else ""),
        ),
        ("boundaries", f"{len(s.boundaries)}" if s.boundaries else "none"),
    ]
    rows += [(f"  [{i}]", _describe_boundary(b)) for i, b in enumerate(s.boundaries)]
    rows += [
        ("provider", _provider_summary(cfg)),
        ("render", f"{cfg.render.width}x{cfg.render.height} @ {cfg.render.fps} fps, backend {cfg.render.backend}"),
    ]
    for key, value in rows:
        print(f"{key:<12}{value}")
    print("ok: config is valid")
    if args.dump:
        print()
        print(dump_config(cfg, header=f"resolved from {path}"), end="")
    return 0
