"""The argparse tree of `fracture-gs`: every command, flag, default and the examples its --help teaches."""

from __future__ import annotations

import argparse
import re
from typing import get_args

from ..config import CaptureMaterial, CaptureQuality, LoadKind, ParticleOrder
from ..io.detect import FORMATS
from . import PROG, CliError
from .sweep import add_sweep_parser

DEVICE_RE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")
RESOLUTION_RE = re.compile(r"\s*([0-9]+)\s*[xX×]\s*([0-9]+)\s*")
BENCH_DEFAULTS = {"steps": 200, "warmup": 20, "trials": 3, "grid": 128, "sort": "cell"}
BENCH_GRID = (8, 256)
"""bench --grid: nodes per axis. The ficus spans [0.1, 0.9] m of the [0, 1) box, which 8 nodes still cover with the
stencil; 256³ is sim.max_grid_cells (16.8 M nodes, ≈ 0.5 GiB of grid buffers), above which the grid is refused."""
MAX_BENCH_PARTICLES = 100_000_000
"""bench --particles: the config's particle cap (io.config.validate.MAX_PARTICLES, ≈ 20 GB of state)."""
"""bench's defaults, applied by `cmd_bench` (the flags default to None, so a flag typed is told from one not)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors become CliError (one line, exit 2). A token that starts with '-' and
    a digit (`-64x48`, `-5`) is a value, never an option, so `--resolution -64x48` reaches the flag's check
    instead of failing as "expected one argument" (no flag of fracture-gs looks like a negative number)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?[0-9]")

    def error(self, message: str):  # type: ignore[override]
        raise CliError(f"{message} (see '{self.prog} --help')")


_MAIN_EPILOG = """\
examples:
  fracture-gs info                                  versions, GPU, renderer backend
  fracture-gs info --warm-up                        compile kernels, gsplat and bytecode once, ahead of use
  fracture-gs validate bread                        check a built-in or your own config
  fracture-gs render-sim bread                      simulate + render the default variants
  fracture-gs render-sim my_capture.ply             your own 3DGS scene, every setting automatic
  fracture-gs render-sim plant.spz                  .splat, .spz and compressed .ply captures too
  fracture-gs init my_capture.ply --out mine.toml   the same settings as a commented TOML to edit
  fracture-gs render-sim configs/recontact.toml --variants local_multifield,full
  fracture-gs render-sim my_scene.toml --preset paper --device cuda:0 --out runs/mine
  fracture-gs bench --device cuda:0                 transfer timings (paper Table 2)
  fracture-gs figures --out figures/out             every table and figure of the paper

A CONFIG is a path to a TOML file, a built-in name ({names}), or a captured scene: a 3DGS .ply,
a compressed .ply (SuperSplat/PlayCanvas), a .splat (antimatter15) or a .spz (Niantic), recognised
by content whatever the file's suffix.
"""

_RENDER_EPILOG = """\
examples:
  fracture-gs render-sim bread
  fracture-gs render-sim bread --variants baseline,full --frames 20 --resolution 320x240
  fracture-gs render-sim configs/exp_table3_bread.toml --preset paper --device cuda:0
  fracture-gs render-sim my_scene.toml --out runs/my_scene
  fracture-gs render-sim point_cloud.ply                       a trainer's PLY, automatic settings
  fracture-gs render-sim point_cloud.ply --load drop --export-ply 5
  fracture-gs render-sim scan.spz --export-ply 5 --export-format spz   frames written as .spz too
  fracture-gs render-sim model.compressed.ply                  .splat, .spz, compressed .ply read too

A captured scene (a 3DGS trainer's .ply, or a .splat, .spz or compressed .ply from a viewer or
editor; its format is read from the content) is prepared automatically: floaters and outliers are
removed, the object is fitted into the grid (up axis from the trainer's cameras.json, else -y), its inside
is filled, a load breaks it (--load pull|drop|impact|shoot|crush) and a camera frames it; what was chosen is
printed and config.toml in --out holds it (`fracture-gs init` writes it with comments).

Writes one folder per variant (frames, metrics.jsonl, topology) and a side-by-side comparison
video under --out (default runs/<config name>). Ctrl-C keeps what was written so far.
"""

_BENCH_EPILOG = """\
examples:
  fracture-gs bench --device cuda:0                 Table 2 at the paper's 171,553 ficus particles
  fracture-gs bench --device cpu --particles 20000 --steps 20   a CPU smoke run
  fracture-gs bench --accuracy --quick              speed against error (Δx and Δt sweeps)
  fracture-gs bench --accuracy --from-json runs/accuracy/accuracy.json   redraw a saved sweep

Table 2 scope (as in the paper): grid reset, P2G, normalization (+ contact), G2P, timed on the
ficus with a latched plane through the trunk (128³ grid, Δx = 1/128). On CUDA: medians of CUDA
events over --steps substeps after warm-up, each branch built --placements times on fresh memory,
plus a per-kernel breakdown. On the CPU: wall-clock medians (Warp runs kernels single-threaded).
Writes bench.json and bench.md (or accuracy.{md,csv,tex,json} and accuracy_pareto.png).
"""

_FIGURES_EPILOG = """\
examples:
  fracture-gs figures                               CPU: quick protocol, every table and figure
  fracture-gs figures --device cuda:0 --out figures/gpu       GPU: paper protocol
  fracture-gs figures --device cuda:0 --only ficus --out figures/gpu            split a long job
  fracture-gs figures --device cuda:0 --only bread,interaction,bench --reuse --out figures/gpu
  fracture-gs figures --readme-only --out figures   rewrite README.md from what the folder holds

Reruns every experiment config (exp_table*.toml) under the paper's protocol and writes Tables 1–5
(Markdown, CSV, LaTeX), the figures, summary.json and a README with the command that made each.
Protocols: quick (CPU sized, the default on the CPU) and paper (Δx = 1/128, the paper's particle
counts, the default on CUDA). Groups for --only: ficus, bread, interaction, bench, fragments (the shatter
figure and the K table).
"""

_INIT_EPILOG = """\
examples:
  fracture-gs init output/garden/point_cloud/iteration_30000/point_cloud.ply --out garden.toml
  fracture-gs init scan.ply --load drop --out scan.toml && fracture-gs render-sim scan.toml
  fracture-gs init plant.splat --out plant.toml     .splat, .spz and compressed .ply captures too

Reads the scene (a 3DGS or compressed .ply, .splat or .spz), removes floaters and outliers, finds
the up axis (the trainer's cameras.json beside it, else -y), picks the region of interest, fits it
into the grid, fills its inside, places the load and the camera, and writes all of it as plain
values with a comment on every key. Edit the file and run it with `fracture-gs render-sim FILE`.
"""

_INFO_EPILOG = """\
examples:
  fracture-gs info
  fracture-gs info --warm-up                        compile everything once, e.g. on a fresh GPU machine
  fracture-gs info --warm-up --device cuda:1

Reports Python, torch, Warp and gsplat versions, CUDA devices, which renderer `--device auto`
picks and why, Warp's kernel cache directory, and whether the packages a run imports have Python
bytecode (without it, and with PYTHONDONTWRITEBYTECODE set, every start compiles their sources
again: seconds for torch). Nothing is compiled, unless --warm-up: then every Warp kernel module
of the simulator and its diagnostics is loaded on the device (compiled where the kernel cache
lacks it), one frame of a tiny scene checks that nothing else is needed, on CUDA gsplat's CUDA
code is built (about a minute the first time), and the missing bytecode is written; each step
prints its time and whether it came from the cache. Later runs then start without compiling.
"""

_VALIDATE_EPILOG = """\
examples:
  fracture-gs validate bread
  fracture-gs validate configs/exp_table5_bread_vlm.toml --dump

Loads the config (following `extends`), checks every key and value, and prints a summary; exit
code 0 when valid, 2 with a one-sentence error otherwise. --dump prints the fully resolved TOML.
"""


def _add_common_run_flags(p: argparse.ArgumentParser, out_help: str) -> None:
    p.add_argument(
        "--device",
        metavar="DEVICE",
        help="auto (default: cuda:0 if available, else cpu), cpu, cuda or cuda:N",
    )
    p.add_argument("--out", metavar="DIR", help=out_help)


def build_parser() -> argparse.ArgumentParser:
    """The full argparse tree (also used by the docs and tests)."""
    from ..io.config import builtin_configs

    fmt = argparse.RawDescriptionHelpFormatter
    parser = _Parser(
        prog=PROG,
        description="Simulate 3D Gaussian Splatting scenes as MLS-MPM particles that fracture "
        "(FractureFields) and render comparison videos.",
        epilog=_MAIN_EPILOG.format(names=", ".join(builtin_configs())),
        formatter_class=fmt,
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser(
        "render-sim",
        help="simulate a scene and render side-by-side variant videos",
        formatter_class=fmt,
        description="Simulate a scene config with several transfer variants and render comparison videos.",
        epilog=_RENDER_EPILOG,
    )
    p.add_argument(
        "config",
        metavar="CONFIG_OR_SCENE",
        help="TOML path, built-in name (e.g. bread) or a captured scene (.ply, .compressed.ply, .splat, .spz)",
    )
    p.add_argument("--variants", metavar="A,B,C", help="comma-separated variants (default: the config's `variants`)")
    p.add_argument(
        "--preset", metavar="small|paper", help="small (dx 1/64, CPU sized) or paper (dx 1/128, paper particle counts)"
    )
    p.add_argument(
        "--frames", metavar="N", type=_positive_int("--frames", 30), help="number of frames (default: the config's)"
    )
    p.add_argument(
        "--particles",
        metavar="N",
        type=_positive_int("--particles", 2000),
        help="built-in scenes only: override the preset's particle count (quick looks)",
    )
    p.add_argument(
        "--resolution", metavar="WxH", type=_resolution, help="image size, e.g. 640x480 (default: the config's)"
    )
    p.add_argument(
        "--load",
        choices=get_args(LoadKind),
        help="captured scenes (splat files): what breaks the object (default: the config's capture.load, auto: a drop)",
    )
    add_capture_options(p)
    p.add_argument(
        "--devices",
        metavar="D1,D2",
        help="run the variants side by side, one per device (e.g. cuda:0,cuda:1): the first device's in this "
        "process, the others' in worker processes (each ≈ 5-8 s to start on a GPU, so it pays off on long runs); "
        "the first variant's fracture topology reaches the others as it latches",
    )
    p.add_argument(
        "--schedule",
        choices=("auto", "in-turn", "threads", "processes"),
        help="on one device: simulate the variants one after another (in-turn), at once in a thread each (threads: "
        "not faster on a GPU, whose frames are Python-bound), or at once in worker processes (processes: Warp runs a "
        "kernel on one core, so on a CPU this is what uses a second core; forked at the start, one per variant up "
        "to two per core; on a GPU one per variant, each with an interpreter of its own: 0.5-1.5 s faster on the "
        "bread paper preset). Default auto: processes on a CPU with two or more cores when the run is long enough "
        "to pay for them, else in-turn. The outputs are the same byte for byte; with threads metrics.jsonl's rows "
        "interleave",
    )
    p.add_argument(
        "--particle-order",
        choices=get_args(ParticleOrder),
        help="sim.particle_order: keep the scene's order (default) or sort the Gaussians by grid cell once before "
        "the run (a GPU's P2G then sums each thread's run of particles in one cell before its atomics: 20-55%% "
        "less P2G time; choices drawn by particle index, such as Voronoi sites, come out differently)",
    )
    p.add_argument(
        "--export-ply",
        metavar="N",
        type=_positive_int("--export-ply", 5),
        help="also write every N-th frame of every variant as a splat file (ply/<variant>/frame_NNNN.*, the scene's "
        "own coordinates), in --export-format",
    )
    p.add_argument(
        "--export-format",
        choices=FORMATS,
        help="with --export-ply: the frames' file format (default ply). ply: 3DGS PLY, lossless, every viewer; "
        "compressed-ply (.compressed.ply): SuperSplat/PlayCanvas, ~4x smaller, quantised, Gaussians reordered; "
        "splat (.splat): antimatter15, colour without view dependence (SH degree 0), 8-bit colour and rotation; "
        "spz (.spz): Niantic, the smallest (4-10x smaller than ply), quantised, SH kept",
    )
    p.add_argument(
        "--profile",
        action="store_true",
        help="print where the wall time goes by phase (simulate, diagnostics, render, compose, encode, io); "
        "also written to profile.md",
    )
    p.add_argument(
        "--view",
        action="store_true",
        help="when the run ends, open it in the viewer (as `fracture-gs view DIR`, on 127.0.0.1:8080)",
    )
    p.add_argument(
        "--no-view-record",
        action="store_true",
        help="do not record the frames for `fracture-gs view` (view/ in --out: 18 bytes per Gaussian, frame and "
        "variant, about 1 GB for 171k Gaussians, 100 frames and 3 variants)",
    )
    p.add_argument(
        "--frames-png",
        action=argparse.BooleanOptionalAction,
        help="also write each comparison frame as frames/compare_NNNN.png (default: on the CPU yes, where they cost "
        "about 1 %% of the run; on CUDA no, where they would cost a tenth of it)",
    )
    _add_common_run_flags(p, "output folder (default: runs/<config name>)")

    p = sub.add_parser(
        "bench",
        help="time the transfer branches (paper Table 2), or speed against error",
        formatter_class=fmt,
        description="Benchmark the transfer branches of the paper's Table 2: speed "
        "and grid memory, then the whole substep (stress + transfer) of the baseline and of FractureFields "
        "after the cut (in its default per-fragment boxes, and in the slot storage for comparison); with "
        "--accuracy, error against wall time on cases with known answers.",
        epilog=_BENCH_EPILOG,
    )
    p.add_argument(
        "--particles",
        metavar="N",
        type=_positive_int("--particles", 20000, MAX_BENCH_PARTICLES),
        help="ficus particle count (default: the paper's 171,553)",
    )
    p.add_argument(
        "--steps",
        metavar="N",
        type=_positive_int("--steps", 200, MAX_BENCH_STEPS),
        help="substeps per timing sample (default 200)",
    )
    p.add_argument(
        "--warmup",
        metavar="N",
        type=_positive_int("--warmup", 20, MAX_BENCH_STEPS),
        help="untimed substeps first (default 20)",
    )
    p.add_argument(
        "--trials",
        metavar="N",
        type=_positive_int("--trials", 3, MAX_BENCH_TRIALS),
        help="timing samples per build (default 3)",
    )
    p.add_argument(
        "--placements",
        metavar="N",
        type=_positive_int("--placements", 5, MAX_BENCH_TRIALS),
        help="fresh-memory builds per branch (default: 5 on CUDA, 1 on the CPU)",
    )
    p.add_argument(
        "--grid",
        metavar="N",
        type=_bench_grid,
        help=f"N³ grid, Δx = 1/N, {BENCH_GRID[0]} to {BENCH_GRID[1]} (default 128)",
    )
    p.add_argument("--no-graph", action="store_true", help="time plain launches, no CUDA graph")
    p.add_argument(
        "--sort",
        choices=("cell", "interleaved"),
        help="particle order (default cell: on a GPU, P2G then sums each thread's run of particles that share a"
        " cell before its atomics)",
    )
    p.add_argument("--accuracy", action="store_true", help="run the speed-against-error sweeps instead of Table 2")
    p.add_argument("--quick", action="store_true", help="with --accuracy: the short sweep (CPU: a few minutes)")
    p.add_argument("--cases", metavar="A,B", help="with --accuracy: a subset of bar, spin, recontact")
    p.add_argument(
        "--from-json", metavar="FILE", help="with --accuracy: only redraw the table and plot of a saved sweep"
    )
    _add_common_run_flags(p, "output folder (default: runs/bench, or runs/accuracy with --accuracy)")

    p = sub.add_parser(
        "figures",
        help="regenerate every table and figure of the paper",
        formatter_class=fmt,
        description="Rerun the paper's experiments and write its tables and figures.",
        epilog=_FIGURES_EPILOG,
    )
    p.add_argument("--protocol", choices=("quick", "paper"), help="quick (CPU default) or paper (CUDA default)")
    p.add_argument(
        "--only", metavar="G1,G2", help="groups to (re)run: ficus, bread, interaction, bench, fragments (default: all)"
    )
    p.add_argument("--reuse", action="store_true", help="load runs cached in OUT/data instead of rerunning them")
    p.add_argument(
        "--backend",
        choices=("auto", "gsplat", "torch", "warp"),
        help="renderer of the scene panels (default: the configs')",
    )
    p.add_argument("--readme-only", action="store_true", help="only rewrite OUT/README.md from what OUT holds")
    _add_common_run_flags(p, "output folder (default: figures/out)")

    p = sub.add_parser(
        "info",
        help="versions, GPU and renderer backend; --warm-up compiles everything once",
        formatter_class=fmt,
        description="Show the software and hardware fracture-gs sees.",
        epilog=_INFO_EPILOG,
    )
    p.add_argument(
        "--warm-up",
        action="store_true",
        help="also compile every Warp kernel module, on CUDA gsplat's CUDA code, and the Python bytecode a run "
        "lacks, once (each step timed)",
    )
    p.add_argument("--device", metavar="DEVICE", help="with --warm-up: auto (default), cpu, cuda or cuda:N")

    p = sub.add_parser(
        "validate",
        help="check a config and print a summary",
        formatter_class=fmt,
        description="Load and check a config without simulating anything.",
        epilog=_VALIDATE_EPILOG,
    )
    p.add_argument("config", metavar="CONFIG", help="TOML path or built-in name")
    p.add_argument("--dump", action="store_true", help="also print the fully resolved config as TOML")

    p = sub.add_parser(
        "init",
        help="write a commented starter config for your own captured scene (.ply, .splat, .spz)",
        formatter_class=fmt,
        description="Resolve every automatic choice for a captured scene and write them as a commented TOML.",
        epilog=_INIT_EPILOG,
    )
    p.add_argument(
        "scene", metavar="SCENE", help="a captured scene: 3DGS or compressed .ply, .splat or .spz (read by content)"
    )
    p.add_argument("--out", metavar="FILE", help="where to write the TOML (default: <scene name>.toml here)")
    p.add_argument("--load", choices=get_args(LoadKind), help="what breaks the object (default auto)")
    add_capture_options(p)
    p.add_argument("--device", default="cpu", help="the device the run will use: sets the resolution budget and panel")
    p.add_argument("--force", action="store_true", help="overwrite FILE if it exists")
    add_sweep_parser(sub)
    add_view_parser(sub)
    return parser


_VIEW_EPILOG = """\
examples:
  fracture-gs view runs/bread                       open http://127.0.0.1:8080 in a browser
  fracture-gs view runs/bread --port 8090           another port
  fracture-gs view runs/bread --max-splats 20000    a browser without a GPU: fewer splats, each widened
  ssh -L 8080:localhost:8080 gpu-box                from your laptop, for a run on gpu-box

Serves the run's recorded frames (RUN_DIR/view/, written by render-sim) as a page that draws the Gaussians as
splats in the browser: orbit, pan and zoom, a frame slider with play/pause, the variants toggled or side by side,
colour by fragment, the fracture band and its interfaces highlighted, the videos' camera as a preset view, and a
button that saves the current view as a PNG (downloaded, and kept in RUN_DIR/views/). Ctrl-C stops it.
"""


def add_view_parser(sub) -> None:
    """`fracture-gs view RUN_DIR [--port N] [--host H] [--preview N]`."""
    p = sub.add_parser(
        "view",
        help="look at a run in 3D in the browser (orbit, scrub frames, compare variants)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Serve a render-sim run's frames as an interactive 3D viewer (viser).",
        epilog=_VIEW_EPILOG,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="the --out folder of a render-sim run")
    p.add_argument("--port", metavar="N", type=_port, default=8080, help="port to listen on (default 8080)")
    p.add_argument(
        "--host",
        metavar="H",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0: every network interface, so "
        "anyone who can reach the machine sees the run)",
    )
    p.add_argument(
        "--preview",
        metavar="N",
        type=int,
        default=20_000,
        help="while the frame changes (scrubbing, playing), first send at most N Gaussians, then the whole frame "
        "once the slider rests; 0 sends every Gaussian at once (default 20000)",
    )
    p.add_argument(
        "--max-splats",
        metavar="N",
        type=int,
        default=0,
        help="draw at most N Gaussians per panel (every k-th, widened to cover the rest), for a browser without a "
        "GPU, whose software WebGL spends 2-20 µs per splat; 0 draws them all (default)",
    )


def _port(text: str) -> int:
    """argparse type for --port: an integer in 1 … 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; write it like --port 8080") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"{value} is not a port (1 … 65535); write it like --port 8080")
    return value


def add_capture_options(p: argparse.ArgumentParser) -> None:
    """--material and --quality: a captured scene's material preset and resolution budget."""
    p.add_argument(
        "--material",
        choices=get_args(CaptureMaterial),
        help="captured scenes: the object's material preset (default ceramic: stiff, brittle; config: [material])",
    )
    p.add_argument(
        "--quality",
        choices=get_args(CaptureQuality),
        help="captured scenes: the resolution budget for the device (default: default; fine resolves thinner parts, "
        "slower)",
    )


MAX_BENCH_STEPS = 100_000
"""Substeps: the most `bench --steps` / `--warmup` take (at ~1 ms a substep on a GPU, 100 s per sample; 10**9 ran
for ever without a word)."""
MAX_BENCH_TRIALS = 1_000
"""The most timing samples (`--trials`) and fresh-memory builds (`--placements`) bench takes."""


def _positive_int(flag: str, example: int, most: int | None = None):
    """argparse type for a count flag (--frames, --particles, --steps, ...): a whole number from 1 to `most`, the
    error's example naming that flag."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer; write it like {flag} {example}") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"{value} must be at least 1")
        if most is not None and value > most:
            raise argparse.ArgumentTypeError(f"{value:,} is more than {most:,}; write it like {flag} {example}")
        return value

    parse.__name__ = flag  # argparse names the type in some messages
    return parse


def _bench_grid(text: str) -> int:
    """argparse type for bench --grid: nodes per axis within BENCH_GRID."""
    value = _positive_int("--grid", 128)(text)
    if not BENCH_GRID[0] <= value <= BENCH_GRID[1]:
        raise argparse.ArgumentTypeError(
            f"{value:,} is outside {BENCH_GRID[0]} to {BENCH_GRID[1]} nodes per axis; write it like --grid 128"
        )
    return value


def _resolution(text: str) -> str:
    """argparse type for --resolution: WxH with positive integers (sizes are checked by the config's overrides).
    Raises CliError itself, so the sentence is printed as written, before any scene is loaded."""
    match = RESOLUTION_RE.fullmatch(text)
    if not match or min(int(match[1]), int(match[2])) < 1:
        raise CliError(
            f"--resolution must be WxH with positive integers, got {text}; write it like --resolution 640x480."
        )
    return text
