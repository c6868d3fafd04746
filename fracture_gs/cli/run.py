"""The commands that run work: render-sim, bench, figures (their modules imported only here, on demand)."""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from ..io.outputs import output_dir, output_file
from . import CliError, in_finalizer
from .devices import resolve_device
from .ignored import refuse_bench, refuse_figures, refuse_render_sim, refuse_scene_flags, run_devices
from .parser import BENCH_DEFAULTS


@contextlib.contextmanager
def sigint_event():
    """A threading Event that Ctrl-C sets, besides raising KeyboardInterrupt as usual. Python drops an
    exception raised in a finalizer (`__del__`, printed as "Exception ignored" with a traceback), and a signal
    handler can run inside one: there the handler only sets the event, and the run stops at its next frame (and
    the command exits 130) because the event is set. Outside the
    main thread (no signal handlers there), or where SIGINT is ignored (a background job of a
    non-interactive shell, as Python leaves it), the event is only returned."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        yield stop
        return

    def handler(signum, frame):
        stop.set()
        if not in_finalizer(frame):  # raised there, Python prints "Exception ignored in ... Traceback" and drops it
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)


def _prepare_warp(init: bool = True) -> None:
    """Warp set up for the CLI (`devices._prepare_warp`), called once a command's flags and config are checked,
    so that a refused flag or a bad config costs no torch or Warp import. Looked up when called: tests
    replace it."""
    from . import devices

    devices._prepare_warp(init)


def _seconds_since_start(args: argparse.Namespace) -> float:
    """Seconds since the process started, when main() is the process's entry point; else since main() began."""
    from ..profiling import process_seconds

    since = process_seconds() if getattr(args, "is_process", False) else None
    return since if since is not None else time.perf_counter() - getattr(args, "entered", time.perf_counter())


def _print_summary(summary: Any) -> None:
    """Print a summary dict as `key: value` lines (JSON for nested values)."""
    if not isinstance(summary, dict):
        if summary is not None:
            print(summary)
        return
    for key, value in summary.items():
        text = value if isinstance(value, (str, int, float)) else json.dumps(value, default=str)
        print(f"{key}: {text}")


def cmd_render_sim(args: argparse.Namespace) -> int:
    """render-sim: load, override, validate, refuse flags that would do nothing, then run (fracture_gs.render_sim)."""
    from ..io.config import apply_overrides, find_config, load_config

    export_format = getattr(args, "export_format", None)
    if export_format and not getattr(args, "export_ply", None):
        raise CliError(f"--export-format {export_format} needs --export-ply N (which frames to write in it).")
    path = find_config(args.config)
    cfg = load_config(path)
    refuse_scene_flags(cfg, args)  # before the overrides: the config's own checks would name the key, not the flag
    cfg = apply_overrides(
        cfg,
        preset=args.preset,
        frames=args.frames,
        resolution=args.resolution,
        variants=args.variants,
        source=f"{path} with command-line overrides",
        keys={"particles": getattr(args, "particles", None), **_key_flags(args)},
    )
    schedule = (getattr(args, "schedule", None) or "auto").replace("-", "_")
    from .devices import fork_safe_cuda_checks

    with fork_safe_cuda_checks(schedule == "processes"):  # its CUDA workers fork after these checks
        device, devices = run_devices(args)  # after the config's checks: `auto` asks torch, which takes seconds
    refuse_render_sim(cfg, args, devices)
    view = getattr(args, "view", False)
    if view:
        if getattr(args, "no_view_record", False):
            raise CliError("--view shows the recorded frames, which --no-view-record turns off; drop one of them.")
        from .view import check_can_serve

        check_can_serve("127.0.0.1", 8080)  # now, not after the run
    out_dir = output_dir(args.out if args.out is not None else Path("runs") / cfg.name)
    from ..profiling import phases

    warp_init = phases.startup.get("warp init", [0.0])[0]
    from ..render_sim.job import forks_cuda_workers

    # the flags and the config are checked: only now torch and Warp load (Warp starts later if CUDA workers fork)
    _prepare_warp(init=not forks_cuda_workers(device, devices, schedule))
    from ..render_sim import run_render_sim as run

    if args.profile:  # the "imports" row: from the process's start (or main()'s, called in a process) to the run
        warp_init = phases.startup.get("warp init", [0.0])[0] - warp_init
        phases.note_startup("imports", max(0.0, _seconds_since_start(args) - warp_init))

    args.partial_out = out_dir
    print(
        f"render-sim: {cfg.name} ({cfg.scene}, preset {cfg.preset}), {cfg.frames} frames, "
        f"variants {', '.join(cfg.variants)}, device {device} -> {out_dir}"
    )
    extra = {"export_ply": args.export_ply} if getattr(args, "export_ply", None) else {}
    if export_format:
        extra["export_format"] = export_format
    if devices and len(devices) > 1:
        extra["devices"] = devices
    else:
        extra["schedule"] = schedule
    if getattr(args, "no_view_record", False):
        extra["record_view"] = False
    if getattr(args, "frames_png", None) is not None:
        extra["frames_png"] = args.frames_png
    with sigint_event() as stop:
        summary = run(cfg, list(cfg.variants), device, out_dir, profile=args.profile, stop=stop, **extra)
    table = out_dir / "summary.md"
    print(table.read_text() if table.exists() else json.dumps(summary.as_dict(), indent=2, default=str))
    from ..render_sim.comparison import frames_png_default

    pngs = extra.get("frames_png", frames_png_default(device))
    print(
        f"outputs in {out_dir}: comparison.mp4, one <variant>.mp4 each, "
        + ("frames/, " if pngs else "")
        + "metrics.jsonl, summary.json, topology.npz, config.toml"
        + ("" if extra.get("record_view") is False else f", view/ (fracture-gs view {out_dir})")
        + ("" if pngs else "; no frames/ PNGs (--frames-png writes them)")
    )
    if summary.profile:
        print(summary.profile, end="")
    from ..render_sim.energy_report import energy_warning

    warning = energy_warning(summary.variants)
    if warning:
        print(f"fracture-gs: warning: {warning}", file=sys.stderr)
    failed = [f"{v['variant']} {v['status']}" for v in summary.variants if v.get("status", "ok") != "ok"]
    if failed:
        print(
            f"fracture-gs: error: {'; '.join(failed)}; every frame and metric written before that is in {out_dir}",
            file=sys.stderr,
        )
    if view:
        from ..viewer.server import serve
        from ..viewer.store import open_run

        serve(open_run(out_dir))
    return 1 if failed else 0


def cmd_bench(args: argparse.Namespace) -> int:
    """bench: Table 2 branches (fracture_gs.paper.bench) or the accuracy sweeps (fracture_gs.paper.accuracy)."""
    redraw = args.accuracy and args.from_json is not None
    device = None if redraw else resolve_device(args.device)
    refuse_bench(args, device)
    payload = _accuracy_payload(args.from_json) if redraw else None
    if args.accuracy:
        from ..paper import accuracy

        cases = _named_list("--cases", args.cases, accuracy.CASES, "bar,spin")
    if not redraw:  # redrawing a saved sweep runs no kernel
        _prepare_warp()
    if args.accuracy:
        out_dir = output_dir(args.out if args.out is not None else Path("runs") / "accuracy")
        args.partial_out = out_dir
        if redraw:
            accuracy.write_outputs(payload, out_dir)
        else:
            _print_summary(accuracy.run_accuracy(device, out_dir, quick=args.quick, cases=cases))
        print((out_dir / "accuracy.md").read_text())
        return 0
    from ..paper.bench import run_bench

    out_dir = output_dir(args.out if args.out is not None else Path("runs") / "bench")
    args.partial_out = out_dir
    sizes = {k: getattr(args, k) if getattr(args, k) is not None else v for k, v in BENCH_DEFAULTS.items()}
    _print_summary(
        run_bench(
            device=device,
            out_dir=out_dir,
            particles=args.particles,
            graph=not args.no_graph,
            placements=args.placements,
            command="fracture-gs " + " ".join(args.argv),
            **sizes,
        )
    )
    return 0


def _named_list(flag: str, text, names, example: str) -> list | None:
    """A comma-separated flag of known names, each once (None: the flag not given, every name)."""
    if text is None:
        return None
    items = [t.strip() for t in text.split(",")]
    if not any(items):
        raise CliError(f"{flag} is empty; list some of {', '.join(names)}, or drop it to run every one.")
    if "" in items:
        raise CliError(f"{flag} {text!r} has an empty entry; write it like {flag} {example}.")
    twice = sorted({t for t in items if items.count(t) > 1})
    if twice:
        raise CliError(f"{flag} {text} lists {', '.join(twice)} twice; list each once.")
    unknown = sorted(set(items) - set(names))
    if unknown:
        raise CliError(f"{flag} {', '.join(unknown)} unknown; choose from {', '.join(names)}.")
    return items


def _accuracy_payload(path_text: str) -> dict:
    """The saved sweep `bench --accuracy --from-json FILE` redraws: an accuracy.json this command wrote, or one
    sentence naming the file and what is wrong with it."""
    from ..paper.accuracy import Result

    if not path_text.strip():
        raise CliError(
            "--from-json is empty; give the accuracy.json of a saved sweep, e.g. runs/accuracy/accuracy.json."
        )
    path = Path(path_text)
    fix = "point --from-json at the accuracy.json that `fracture-gs bench --accuracy` writes"
    if path.is_dir():
        raise CliError(f"--from-json {path} is a folder; {fix}, e.g. {path / 'accuracy.json'}.")
    if not path.is_file():
        raise CliError(f"--from-json {path}: no such file; {fix}.")
    try:
        payload = json.loads(path.read_bytes().decode("utf-8-sig"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CliError(f"--from-json {path} is not JSON ({' '.join(str(exc).split())[:80]}); {fix}.") from None
    keys = ("results", "caption", "command", "device_name")
    if not isinstance(payload, dict) or any(k not in payload for k in keys) or not isinstance(payload["results"], list):
        raise CliError(f"--from-json {path} is not a saved accuracy sweep (no {', '.join(keys)}); {fix}.")
    from ..io.config.validate import is_finite_number

    for i, r in enumerate(payload["results"]):
        try:
            Result(**r)
        except TypeError:
            raise CliError(f"--from-json {path}: results[{i}] is not a sweep result; {fix}.") from None
        bad = next((k for k in ("dx", "dt", "cfl", "wall_s", "error") if not is_finite_number(r[k])), None)
        if bad is not None or not r["dx"] > 0:
            raise CliError(f"--from-json {path}: results[{i}].{bad or 'dx'} is not a usable number; {fix}.")
    return payload


def cmd_figures(args: argparse.Namespace) -> int:
    """figures: regenerate the paper's tables and figures (fracture_gs.paper.figures)."""
    from ..paper.figures import GROUPS, run_figures
    from ..paper.readme import refresh_readme

    refuse_figures(args)
    if args.out is not None and not args.out.strip():
        output_dir(args.out)  # refuses an empty --out in one line (Path("") would be the current folder)
    out = Path(args.out) if args.out is not None else Path("figures") / "out"
    if args.readme_only and not (out / "summary.json").is_file():
        raise CliError(
            f"--readme-only rewrites README.md from a figures folder's summary.json, and {out} holds none; run "
            f"`fracture-gs figures --out {out}` first, or point --out at such a folder."
        )
    out_dir = output_dir(out)
    if args.readme_only:
        _check_summary(out / "summary.json")
        print(refresh_readme(out_dir))
        return 0
    only = _figure_groups(args.only, GROUPS)
    if only is not None and args.backend is not None and not {"ficus", "bread"} & set(only):
        raise CliError(
            f"--backend draws the ficus and bread scene panels only, and --only {args.only} runs neither; drop "
            "--backend or add ficus or bread to --only."
        )
    if only is not None and args.reuse and not any(GROUPS[g] for g in only):
        raise CliError(
            f"--reuse loads cached simulation runs, and --only {args.only} runs none (bench times the solver "
            "afresh); drop --reuse."
        )
    device = resolve_device(args.device)
    if args.backend is not None:
        on_cuda = device.startswith("cuda")
        if (args.backend == "gsplat" and not on_cuda) or (args.backend == "warp" and on_cuda):
            raise CliError(
                f"--backend {args.backend} cannot draw on {device} (gsplat draws on CUDA only, warp on the CPU only); "
                "use --backend auto or torch."
            )
    _prepare_warp()
    args.partial_out = out_dir
    command = "fracture-gs " + " ".join(args.argv)
    _print_summary(
        run_figures(
            device,
            out_dir,
            protocol=args.protocol,
            only=only,
            reuse=args.reuse,
            command=command,
            render_backend=args.backend,
        )
    )
    return 0


def _check_summary(path: Path) -> None:
    """--readme-only reads the figures folder's summary.json: a JSON object with the run's `meta`, as `figures`
    writes it, or one sentence naming the file."""
    fix = f"rerun `fracture-gs figures --out {path.parent}` to write it again, or point --out at another figures folder"
    try:
        summary = json.loads(path.read_bytes().decode("utf-8-sig"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CliError(f"{path} is not JSON ({' '.join(str(exc).split())[:80]}); {fix}.") from None
    meta = summary.get("meta") if isinstance(summary, dict) else None
    need = ("command", "date", "device_name", "wall_s", "device", "out_arg")
    if not isinstance(meta, dict) or any(k not in meta for k in need) or not isinstance(meta["wall_s"], (int, float)):
        raise CliError(f"{path} is not a figures summary (no 'meta' with {', '.join(need)}); {fix}.")
    entries = summary.get("figure_entries", [])
    keys = ("path", "title", "caption", "function")
    if not isinstance(entries, list) or not all(isinstance(e, dict) and all(k in e for k in keys) for e in entries):
        raise CliError(f"{path}: figure_entries is not a list of figures with {', '.join(keys)}; {fix}.")


def _figure_groups(text, groups) -> list | None:
    """--only as a list of known groups, each once (None: every group)."""
    return _named_list("--only", text, groups, "bread,bench")


def cmd_init(args: argparse.Namespace) -> int:
    """init: resolve a captured scene's automatic choices and write them as a commented TOML."""
    from ..capture.scene import resolve
    from ..capture.starter import starter_toml
    from ..io.config import apply_overrides, load_config
    from ..io.detect import READ, is_splat_file

    ply = Path(args.scene)
    if not is_splat_file(ply):
        raise CliError(
            f"{ply}: init takes a captured scene ({READ}); for a TOML config use `fracture-gs validate {ply}`."
        )
    cfg = apply_overrides(load_config(ply), source=f"{ply} with command-line overrides", keys=_key_flags(args))
    out = output_file(args.out if args.out is not None else Path(f"{cfg.name}.toml"))
    if out.exists() and out.resolve() == ply.resolve():
        raise CliError(
            f"--out {out} is the scene file itself, which init would overwrite with its TOML; choose another --out, "
            f"e.g. --out {ply.with_suffix('.toml').name}."
        )
    if out.suffix.lower() != ".toml":  # a TOML under x.ply read back as a (broken) scene, not as the config
        raise CliError(
            f"--out {out} does not end in .toml, and init writes a TOML config that render-sim reads by that "
            f"suffix; use e.g. --out {out.with_suffix('.toml')}."
        )
    if out.exists() and not args.force:
        raise CliError(f"{out} exists; pass --force to overwrite it or choose another --out.")
    capture = resolve(cfg, resolve_device(args.device))
    out.write_text(starter_toml(capture, str(ply)))
    for note in capture.notes:
        print(f"  {note}")
    print(f"wrote {out}: edit it, then run  fracture-gs render-sim {out}")
    return 0


def _key_flags(args: argparse.Namespace) -> dict:
    """--load, --material, --quality and --particle-order as the TOML keys they set (None: not given)."""
    flags = {"capture.load": "load", "capture.material": "material", "capture.quality": "quality"}
    flags["sim.particle_order"] = "particle_order"
    return {key: getattr(args, flag, None) or None for key, flag in flags.items()}
