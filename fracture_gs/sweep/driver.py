"""`run_sweep`: a sweep spec's cells, spread over the ranks of a launch, cached, gathered, tabled.

Every rank reads the spec itself and expands it to the same ordered cell list (rank 0 checks that
they agree). Cells already cached (OUT/cells/<id>.json, on any rank's disk, from a run on the same
device type) are not run again: failed ones neither, unless `rerun_failed`; `fresh` ignores the
cache. The remaining cells are dealt out by estimated cost, longest first to the least-loaded rank
(`deal`; equal costs go round-robin), so ranks finish together, fresh or resumed. A rank prints one line per finished
cell, `[rank r/W] k/n cell i/N <id> <what>: ok 1.2 s ...`.

A cell that raises becomes a failed row carrying its error sentence (the traceback stays in its
cache file); it never stops the sweep. Rank 0 writes sweep.md, sweep.tex, sweep.csv, sweep.json
and, with accuracy cells and matplotlib, sweep_pareto.png — also when cells failed or a rank died
(its unfinished cells are then `missing`).

On the CPU each rank runs torch with one thread while it works (Warp's CPU kernels are serial):
a machine's cores are used by ranks, one per core, and results do not depend on the thread count.
"""

from __future__ import annotations

import datetime
import hashlib
import os
import signal
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Optional

from . import cache
from .cells import run_cell, warmup
from .distributed import Launch, coordinator, launch_from_env, resolve_device
from .expansion import Cell, expand, iter_cells
from .report import write_outputs
from .spec import SweepSpec, load_spec

RUN_KEYS = frozenset({"rank", "world_size", "device_name", "finished", "traceback"})
"""Row keys that describe where and when a cell ran, not what it measured."""


@dataclass
class SweepOptions:
    """How to run a sweep (the CLI's flags)."""

    out_dir: Path
    """Output folder: sweep.{md,tex,csv,json}, sweep_pareto.png, cells/<id>.json."""
    device: str = "auto"
    """auto | cpu | cuda (each rank: cuda:LOCAL_RANK) | cuda:N (one process only)."""
    fresh: bool = False
    """Ignore the cache: run every cell again (its cache file is overwritten)."""
    rerun_failed: bool = False
    """Run the cells whose cached result is a failure again."""
    rank_timeout_s: float = 300.0
    """Seconds a rank may go without a heartbeat before it counts as dead; also the process group's timeout [s]."""
    beat_s: float = 2.0
    """Heartbeat period [s]."""
    command: str = ""
    """The command line, recorded in sweep.md and sweep.json."""
    max_cells: Optional[int] = None
    """The most cells the spec may multiply out to (`--max-cells`); None = the spec's `[sweep] max_cells`."""
    echo: Callable[[str], None] = field(default=lambda line: print(line, flush=True))
    """Where progress lines go."""


@dataclass
class SweepReport:
    """What a sweep did, as seen by one rank (rank 0 also holds the rows and the files)."""

    rank: int
    world_size: int
    device: str
    cells: int
    ran: int
    """Cells this rank ran now."""
    rows: list = field(default_factory=list)
    """Rank 0: one row per cell, in cell order; other ranks: empty."""
    files: list = field(default_factory=list)
    """Rank 0: the files written."""
    failure: Optional[Exception] = None
    """Rank 0: a RankFailure when a rank died (the tables are written anyway)."""

    @property
    def failed(self) -> list:
        return [r for r in self.rows if r.get("status") != "ok"]


def _message(exc: BaseException) -> str:
    from ..errors import FractureGSError

    text = " ".join(str(exc).split())
    if not isinstance(exc, FractureGSError) or not text:
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= 400 else text[:397] + "..."


def base_row(cell: Cell) -> dict:
    """The parameters every row of `cell` starts with."""
    return {"index": cell.index, "id": cell.id, "kind": cell.kind, "labels": "+".join(cell.labels), **cell.info}


def run_one(cell: Cell, launch: Launch, device: str, out_dir: Path) -> dict:
    """Run one cell and return its row (a failure is a row, not an exception)."""
    row = base_row(cell)
    t0 = time.perf_counter()
    try:
        outcome = run_cell(cell, device, out_dir)
        row.update(outcome.metrics)
        row["status"] = "ok" if outcome.status == "ok" else "failed"
        row["message"] = "" if outcome.status == "ok" else outcome.status
        if outcome.extra:
            row["extra"] = outcome.extra
    except Exception as exc:  # noqa: BLE001 - a failing cell is a table row, never the end of the sweep
        row["status"], row["message"] = "failed", _message(exc)
        row["traceback"] = traceback.format_exc()
    row.update(
        cell_s=time.perf_counter() - t0,
        rank=launch.rank,
        world_size=launch.world_size,
        device=device,
        device_name=_device_name(device),
        finished=datetime.datetime.now().isoformat(timespec="seconds"),
    )
    return row


def _device_name(device: str) -> str:
    if device.startswith("cuda"):
        import torch

        return torch.cuda.get_device_name(torch.device(device))
    import platform

    return f"CPU ({platform.processor() or platform.machine()})"


def ids_digest(cells: list[Cell]) -> str:
    """A digest of the ordered cell ids: ranks that expanded the spec differently must not share a plan."""
    return hashlib.sha256(",".join(c.id for c in cells).encode()).hexdigest()[:16]


def deal(pending: list[Cell], world: int) -> list[list[int]]:
    """Longest estimated cell first to the least-loaded rank (LPT; ties to the lower cell index and
    rank), each rank's cells then in index order. Deterministic; cells of equal cost go round-robin
    (pending j → rank j mod W). On the quick and full accuracy sweeps this keeps two ranks within a few
    per cent of each other, where plain round-robin left one rank 28 % longer."""
    loads, assign = [0.0] * world, [[] for _ in range(world)]
    for c in sorted(pending, key=lambda c: (-c.cost, c.index)):
        r = min(range(world), key=lambda r: (loads[r], r))
        assign[r].append(c.index)
        loads[r] += c.cost
    return [sorted(a) for a in assign]


def make_plan(cells: list[Cell], statuses: list[dict], world: int, rerun_failed: bool) -> dict:
    """Rank 0's plan from every rank's {id: cached status}: who holds each reusable cell (the lowest
    rank), the pending cells dealt out by estimated cost (`deal`), and which cached rows
    each rank must send to rank 0."""
    holder: dict[str, int] = {}
    for r, status in enumerate(statuses):
        for cid, s in status.items():
            if (s == "ok" or not rerun_failed) and cid not in holder:
                holder[cid] = r
    pending = [c for c in cells if c.id not in holder]
    return {
        "digest": ids_digest(cells),
        "assign": deal(pending, world),
        "send": [[cid for cid, h in holder.items() if h == r] if r else [] for r in range(world)],
        "cached": len(holder),
    }


def iter_listing(spec_path, opts: SweepOptions) -> Iterator[tuple[Cell, str, Optional[int]]]:
    """(cell, cache status, rank it would run on now) for every cell, `ok`/`failed` (cached) or `pending`, one cell at
    a time as the spec expands: with one rank the plan is known per cell (a cell
    to run goes to rank 0), so the first lines come at once however many cells follow; with several ranks the
    cost-balanced plan needs every cell first."""
    spec = load_spec(spec_path)
    launch = launch_from_env()
    device = resolve_device(opts.device, launch)
    if not opts.fresh:
        cache.check_folder(cache.cells_dir(opts.out_dir))  # before the first line, not inside the generator
    return _listing(spec, launch, device.split(":")[0], opts)


def _listing(spec, launch: Launch, device_type: str, opts: SweepOptions) -> Iterator[tuple[Cell, str, Optional[int]]]:
    if launch.world_size == 1:
        for cell in iter_cells(spec, opts.max_cells):
            row = None if opts.fresh else cache.lookup(opts.out_dir, cell, device_type)
            status = "pending" if row is None else row.get("status", "failed")
            reused = status == "ok" or (status == "failed" and not opts.rerun_failed)
            yield cell, status, None if reused else 0
        return
    cells = expand(spec, opts.max_cells)
    found = {} if opts.fresh else cache.scan(opts.out_dir, cells, device_type)
    statuses = [{k: v.get("status", "failed") for k, v in found.items()}]
    plan = make_plan(cells, statuses, launch.world_size, opts.rerun_failed)
    where = {i: r for r, idx in enumerate(plan["assign"]) for i in idx}
    for c in cells:
        yield c, found[c.id].get("status", "failed") if c.id in found else "pending", where.get(c.index)


def _sigterm_note(launch: Launch, out_dir: Path, counter: list):
    """A SIGTERM handler (torchrun stops every rank when one fails) that says what is kept."""

    def handler(signum, frame):
        print(
            f"{launch.tag} stopped by signal {signum} (torchrun stops every rank when one fails); the {counter[0]} "
            f"cell(s) this rank finished are cached in {cache.cells_dir(out_dir)}; rerun the same command to resume.",
            file=sys.stderr,
            flush=True,
        )
        os._exit(128 + signum)

    return handler


def run_sweep(spec_path, opts: SweepOptions, cells: Optional[list[Cell]] = None) -> SweepReport:
    """Run the sweep on this rank; rank 0 gathers and writes the tables. See the module docstring. `cells`:
    the spec's expansion when the caller made it already (it takes a while for many scene cells)."""
    spec: SweepSpec = load_spec(spec_path)
    cells = expand(spec, opts.max_cells) if cells is None else cells
    launch = launch_from_env()
    device = resolve_device(opts.device, launch)
    out = Path(opts.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    echo, tag = opts.echo, launch.tag
    found = {} if opts.fresh else cache.scan(out, cells, device.split(":")[0])
    done = [0]
    previous = None
    if launch.distributed and threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _sigterm_note(launch, out, done))
    try:
        with coordinator(launch, device, opts.rank_timeout_s, opts.beat_s) as coord:
            statuses = {cid: row.get("status", "failed") for cid, row in found.items()}
            plan = coord.plan(statuses, lambda s: make_plan(cells, s, launch.world_size, opts.rerun_failed))
            if plan["digest"] != ids_digest(cells):
                from .distributed import LaunchError

                raise LaunchError(
                    f"{tag} expanded {spec.source} to other cells than rank 0 did; every rank must read the same "
                    "spec and configs (copy them to every node, or use a shared folder)."
                )
            mine = [cells[i] for i in plan["assign"][launch.rank]]
            backend = getattr(coord, "backend", "no process group")
            echo(
                f"{tag} {device} ({backend}): {len(mine)} of {len(cells)} cells to run here, "
                f"{plan['cached']} cached in {cache.cells_dir(out)}"
            )
            rows = _run_mine(spec, mine, len(cells), launch, device, out, echo, done)
            for cid in plan["send"][launch.rank]:
                rows[cid] = found[cid]
            gathered = coord.finish(rows)
            report = SweepReport(launch.rank, launch.world_size, device, len(cells), len(mine))
            if gathered is None:
                echo(f"{tag} done: {len(mine)} cell(s) run, results handed to rank 0")
                return report
            report.failure = coord.failure()
            report.rows = _merge(out, device, cells, found, gathered, report.failure)
            _complete_cache(out, cells, report.rows)
            report.files = write_outputs(out, spec, report.rows, launch.world_size, opts.command)
            return report
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _run_mine(spec, mine: list[Cell], total: int, launch: Launch, device: str, out: Path, echo, done: list) -> dict:
    """Run this rank's cells in order, caching and printing each; returns {id: row}."""
    import torch

    rows: dict[str, dict] = {}
    if not mine:
        return rows
    threads = torch.get_num_threads()
    if not device.startswith("cuda"):
        torch.set_num_threads(1)
    try:
        if spec.warmup:
            t0 = time.perf_counter()
            warmup(device)
            echo(f"{launch.tag} warm-up (kernels compiled and loaded) {time.perf_counter() - t0:.1f} s")
        for k, cell in enumerate(mine, 1):
            row = run_one(cell, launch, device, out)
            cache.store(out, cell, row)
            rows[cell.id] = row
            done[0] += 1
            where = f"{launch.tag} {k}/{len(mine)} cell {cell.index + 1}/{total} {cell.id}"
            echo(f"{where} {cell.describe}: {_result(row)}")
    finally:
        torch.set_num_threads(threads)
    return rows


def _result(row: dict) -> str:
    """The tail of a progress line: status, seconds, the headline metric."""
    text = f"{row['status']} {row['cell_s']:.1f} s"
    if row["status"] != "ok":
        return f"{text}: {row['message']}"
    if row["kind"] == "accuracy":
        return f"{text}, error {row['error']:.3e} ({row['unit']})"
    keys = ("latch_frame", "opening", "penetration_max", "substeps")
    return text + "".join(
        f", {k} {row[k]}" if isinstance(row[k], int) else f", {k} {row[k]:.3g}"
        for k in keys
        if isinstance(row.get(k), (int, float)) and not isinstance(row.get(k), bool)
    )


def _merge(out: Path, device: str, cells: list[Cell], found: dict, gathered: list[dict], failure) -> list[dict]:
    """One row per cell, in cell order: gathered rows first, then this disk's cache (a dead rank's
    finished cells on a shared folder), else a `missing` row."""
    by_id: dict[str, dict] = dict(found)
    for rows in gathered:
        by_id.update(rows)
    if failure is not None:
        rest = [c for c in cells if c.id not in by_id]  # a dead rank's finished cells, on a shared folder
        by_id.update(cache.scan(out, rest, device.split(":")[0]))
    merged = []
    for cell in cells:
        row = by_id.get(cell.id)
        if row is None:
            rank = f"rank {failure.rank} stopped" if failure is not None else "no rank ran it"
            row = {**base_row(cell), "status": "missing", "message": f"not run ({rank}); rerun the sweep to resume"}
        merged.append({**row, **base_row(cell)})
    return merged


def _complete_cache(out: Path, cells: list[Cell], rows: list[dict]) -> None:
    """Rank 0 keeps a complete cache: rows gathered from other nodes (no shared folder) are written here too."""
    for cell, row in zip(cells, rows):
        if row.get("status") != "missing" and cache.load(out, cell) is None:
            cache.store(out, cell, row)
