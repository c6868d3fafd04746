"""`fracture-gs sweep SPEC`: a grid of independent runs (fracture_gs.sweep), one rank or many.

Wired into the main parser by `add_sweep_parser(subparsers)` and `_COMMANDS["sweep"] = cmd_sweep`;
`python -m fracture_gs.cli.sweep SPEC ...` is the same command through `fracture_gs.cli.main`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Optional, Sequence

PROG = "fracture-gs"
TABLE_FILES = ("sweep.md", "sweep.tex", "sweep.csv", "sweep.json", "sweep_pareto.png")
"""The files rank 0 writes in --out once every cell has run (`sweep.report`)."""
MAX_RANK_TIMEOUT_S = 604_800
"""The longest --rank-timeout: a week (torch's timedelta overflows on inf; no rank is meant to wait longer)."""

SWEEP_EPILOG = """\
examples:
  fracture-gs sweep accuracy --list                      the cells, their cache status and ranks
  fracture-gs sweep configs/sweeps/accuracy.toml         = bench --accuracy --quick, resumable
  fracture-gs sweep configs/sweeps/scenes.toml --device cpu --out runs/scenes
  torchrun --nproc-per-node 2 -m fracture_gs.cli sweep configs/sweeps/accuracy.toml --device cuda
                                                         one GPU per rank (cuda:LOCAL_RANK), NCCL
  torchrun --nproc-per-node 2 -m fracture_gs.cli sweep configs/sweeps/accuracy.toml --device cpu
                                                         two CPU processes, gloo
  torchrun --nnodes 2 --node-rank 0 --master-addr HOST0 --master-port 29500 --nproc-per-node 8 \\
      -m fracture_gs.cli sweep my_sweep.toml --device cuda --out /shared/runs/my_sweep   (and node-rank 1)

A SPEC is a TOML file or a built-in name ({names}). Tables, each a cross product:
  [[accuracy]] case = ["bar", "spin", "recontact"], cells = [16, 32] (Δx = 1/cells), cfl = [0.4]
  [[scene]]    config = ["recontact"], variant = [...], cells = [32, 64], dt = [...] or cfl = [...],
               seed = [0, 1], frames = 10, particles = 2000, [scene.material] E = [...], nu = [...],
               [scene.set] "any.config.key" = [...], render = false (true: render-sim's videos too)
(the format: fracture_gs/sweep/spec.py; the built-in specs are commented examples).

A spec may multiply out to at most 10,000 cells ([sweep] max_cells or --max-cells N raises the cap); the
count is checked before any cell is made, and --list prints the cells as they are made.

Cells are dealt out by estimated cost (longest first to the least-loaded rank, so ranks finish together;
`--list` shows the plan); each finished cell is cached in OUT/cells/<id>.json (id = a hash of
its parameters and resolved config), so rerunning the same command, with any number of ranks, runs only
what is missing. Rank 0 writes OUT/sweep.md, sweep.tex, sweep.csv, sweep.json and sweep_pareto.png
(accuracy cells, matplotlib). docs/scaling.md: 1 GPU, N GPUs, M machines, failures.

exit codes: 0 every cell ok; 1 some cells failed (each is a row with its error; the tables are written;
--rerun-failed retries them); 2 a bad spec, flag, device or launch (one sentence); 3 a rank died or stopped
answering (rank 0 still writes the tables, its unfinished cells marked missing; rerun to resume);
130 interrupted (finished cells stay cached).
"""


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds; write it like 300") from None
    if not 0 < value <= MAX_RANK_TIMEOUT_S:
        raise argparse.ArgumentTypeError(
            f"{value:g} must be a positive number of seconds up to {MAX_RANK_TIMEOUT_S:,} (a week)"
        )
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text.replace("_", "").replace(",", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number; write it like 20000") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be a positive number of cells")
    return value


def add_sweep_parser(subparsers, parser_class: Optional[type] = None) -> argparse.ArgumentParser:
    """Add the `sweep` subcommand to an argparse subparsers object (`parser_class`: the class its
    parser should be, e.g. the CLI's one-line-error parser; default: the subparsers' own)."""
    from ..sweep import builtin_specs

    saved = getattr(subparsers, "_parser_class", None)
    if parser_class is not None:
        subparsers._parser_class = parser_class
    try:
        p = subparsers.add_parser(
            "sweep",
            help="run a grid of independent simulations (one process or a torchrun launch), cached and tabled",
            formatter_class=argparse.RawDescriptionHelpFormatter,
            description="Run every cell of a sweep spec (accuracy cases × Δx × CFL, scene configs × variants × "
            "settings × seeds), spread over the ranks of a torchrun launch, and write one table of their metrics.",
            epilog=SWEEP_EPILOG.format(names=", ".join(builtin_specs()) or "none installed"),
        )
    finally:
        if parser_class is not None:
            subparsers._parser_class = saved
    p.add_argument("spec", metavar="SPEC", help="sweep spec: a TOML path or a built-in name (e.g. accuracy)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: runs/<spec file stem>)")
    p.add_argument(
        "--device",
        default="auto",
        metavar="DEVICE",
        help="auto (default: cuda if there is a GPU, else cpu), cpu, cuda (rank r: cuda:LOCAL_RANK) or cuda:N "
        "(one process only)",
    )
    p.add_argument("--list", action="store_true", help="print the cells, their cache status and rank, and exit")
    p.add_argument("--rerun-failed", action="store_true", help="run cells whose cached result is a failure again")
    p.add_argument("--fresh", action="store_true", help="ignore the cache and run every cell again")
    p.add_argument(
        "--max-cells",
        metavar="N",
        type=_positive_int,
        help="the most cells the spec may multiply out to (default: its [sweep] max_cells, else 10,000)",
    )
    p.add_argument(
        "--rank-timeout",
        metavar="S",
        type=_positive_seconds,
        default=None,
        help="seconds without a heartbeat after which a rank counts as dead (default 300)",
    )
    return p


def _print_list(spec_path, opts, total: int) -> None:
    """The cells with their cache status and rank, printed as the spec expands (the first lines come at once
    with one rank), then the counts."""
    from ..sweep.distributed import launch_from_env
    from ..sweep.driver import iter_listing

    launch = launch_from_env()
    listing = iter_listing(spec_path, opts)
    if launch.rank != 0:
        for _ in listing:
            pass
        return
    print(f"{spec_path}: up to {total:,} cells (cache {opts.out_dir / 'cells'})", flush=True)
    print(f"{'#':>4}  {'id':<12}  {'kind':<8}  {'cache':<7}  {'rank':>4}  cell", flush=True)
    counts = {"ok": 0, "failed": 0, "pending": 0}
    for cell, status, rank in listing:
        where = "-" if rank is None else str(rank)
        print(
            f"{cell.index + 1:>4}  {cell.id:<12}  {cell.kind:<8}  {status:<7}  {where:>4}  {cell.describe}", flush=True
        )
        counts[status if status in counts else "failed"] += 1
    print(
        f"{sum(counts.values())} cells in {spec_path} (cache {opts.out_dir / 'cells'}): {counts['ok']} ok, "
        f"{counts['failed']} failed, {counts['pending']} to run on {launch.world_size} rank(s)"
    )


def _progress(echo_every_s: float = 5.0):
    """A progress callback for a long expansion: one line every few seconds (none for a quick one)."""
    import time

    start = last = time.monotonic()

    def report(made: int, total: int) -> None:
        nonlocal last
        now = time.monotonic()
        if now - last >= echo_every_s:
            last = now
            print(f"sweep: made {made:,} of {total:,} cells ({now - start:.0f} s)", flush=True)

    return report


def _refuse_ignored(args: argparse.Namespace) -> None:
    """Flags that would change nothing are refused (cli/ignored.py's rule): --list only reads the cache."""
    from . import CliError

    if args.list:
        for flag, given in (
            ("--fresh", args.fresh),
            ("--rerun-failed", args.rerun_failed),
            ("--rank-timeout", args.rank_timeout is not None),
        ):
            if given:
                raise CliError(f"{flag} does nothing with --list, which only reads the cache; drop {flag} or --list.")
    if args.fresh and args.rerun_failed:
        raise CliError("--rerun-failed does nothing beside --fresh, which runs every cell again; keep one of them.")


def cmd_sweep(args: argparse.Namespace) -> int:
    """sweep: run (or --list) a spec's cells on this rank; rank 0 prints the summary and the table. Bad input
    raises the package's errors (one line from the CLI)."""
    _refuse_ignored(args)
    from ..io.outputs import check_output_paths, output_dir
    from ..sweep import expand, find_spec, load_spec
    from ..sweep.distributed import RankFailure, launch_from_env, resolve_device
    from ..sweep.driver import SweepOptions, run_sweep

    path = find_spec(args.spec)
    cells, total = None, 0
    if args.list:  # checks the size only: the cells are checked as they are listed
        from ..sweep.expansion import check_size

        total = check_size(load_spec(path), args.max_cells)
    else:  # a bad spec, launch or device is one sentence before any folder is made
        cells = expand(load_spec(path), args.max_cells, _progress())
    launch = launch_from_env()
    resolve_device(args.device, launch)
    if args.rank_timeout is not None and not launch.distributed:
        from . import CliError

        raise CliError(
            f"--rank-timeout {args.rank_timeout:g} has no effect on a single-process sweep (there are no other ranks "
            "to wait for); drop it, or launch the ranks with torchrun."
        )
    if args.out is not None and not args.out.strip():
        output_dir(args.out)  # refuses an empty --out in one line (Path("") would be the current folder)
    out = Path(args.out) if args.out is not None else Path("runs") / path.stem
    if not args.list:  # --list only reads the cache
        out = output_dir(out)
        check_output_paths(out, files=TABLE_FILES)  # the tables are written last: a folder in the way fails now
        args.partial_out = out
    argv = getattr(args, "argv", None) or ["sweep", *sys.argv[1:]]
    opts = SweepOptions(
        out_dir=out,
        device=args.device,
        fresh=args.fresh,
        rerun_failed=args.rerun_failed,
        rank_timeout_s=300.0 if args.rank_timeout is None else args.rank_timeout,
        command="fracture-gs " + " ".join(argv),
        max_cells=args.max_cells,
    )
    if args.list:
        _print_list(path, opts, total)
        return 0
    from .devices import _prepare_warp

    _prepare_warp()
    try:
        report = run_sweep(path, opts, cells)
    except RankFailure as exc:
        print(f"{PROG}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 3
    if report.rank != 0:
        return 0
    failed = report.failed
    ok = len(report.rows) - len(failed)
    print(
        f"sweep: {len(report.rows)} cells, {ok} ok, {len(failed)} not ok ({report.ran} run on rank 0, "
        f"world size {report.world_size}) -> {out}: {', '.join(report.files)}"
    )
    if len(report.rows) <= 40:
        print((out / "sweep.md").read_text())
    if report.failure is not None:
        print(f"{PROG}: error: {' '.join(str(report.failure).split())}", file=sys.stderr)
        return 3
    if failed:
        first = failed[0]
        print(
            f"{PROG}: error: {len(failed)} of {len(report.rows)} cells failed (first: {first['id']}, "
            f"{first.get('message', '')}); the tables in {out} mark them; fix the cause and rerun with --rerun-failed.",
            file=sys.stderr,
        )
        return 1
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """`python -m fracture_gs.cli.sweep SPEC ...`: the subcommand on its own, through the CLI's entry
    point (the same parsing, one-line errors, exit codes and Ctrl-C handling as `fracture-gs sweep`)."""
    from . import main as cli_main

    return cli_main(["sweep", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
