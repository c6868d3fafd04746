"""Run one sweep cell on one device → a flat dict of metrics.

Two kinds:

* ``accuracy`` — one (case, Δx, CFL) setting of `fracture_gs.paper.accuracy` (bar, spin,
  recontact): the case function itself, so a sweep cell and `fracture-gs bench --accuracy` give the
  same numbers. Metrics: Δt, particles, substeps, wall time of the timed run (after warm-up), error
  and its unit, the case's extras (measured period, energy drift, penetration in Δx, ...).
* ``scene`` — a scene config (built-in or PLY) with one variant: the simulation of render-sim
  without drawing (frame loop, event provider, per-frame diagnostics), summarised exactly as
  render-sim's summary.json (`fracture_gs.render_sim.summarize`): latch frame, opening, re-approach,
  stringing, mixing, mass residual, penetration, fragments, slot overflow, contact numbers, wall
  time and substeps/s. With ``render = true`` the cell runs `run_render_sim` instead (videos and
  frames under OUT/cells/<id>/), which costs the rendering time too.

Each run is deterministic for its parameters on the CPU (one torch thread per rank, Warp's CPU
kernels are serial), so a cell gives the same metrics on any rank of any world size; on CUDA the
order of floating-point atomic adds varies from run to run, so metrics agree to float32 round-off
(measured on two H200s: the bar's period error in its 4th digit, the re-contact opening in its 7th).
Wall-time keys (`WALL_KEYS`) differ between runs by nature.

A scene whose simulation diverges is not an exception here: the metrics up to the divergence are
returned with status "diverged at frame k: cause" (the sweep counts it as failed).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from .expansion import Cell

WALL_KEYS = frozenset({"wall_s", "cell_s", "substeps_per_s"})
"""Row keys measured in seconds of wall time (they differ between two runs of the same cell)."""


@dataclass
class Outcome:
    """What running one cell gave."""

    metrics: dict
    """Flat JSON-able metrics (numbers, strings, booleans, None)."""
    status: str = "ok"
    """`ok`, or why the run stopped early (e.g. `diverged at frame 12: ...`)."""
    extra: dict = field(default_factory=dict)
    """Non-flat results kept in the cache file only (e.g. the latch record)."""


def _sync(device: str) -> None:
    if str(device).startswith("cuda"):
        import torch

        torch.cuda.synchronize(device)


def run_cell(cell: Cell, device: str, out_dir: Optional[Path] = None) -> Outcome:
    """Run `cell` on `device`; exceptions propagate (the driver records them as failed rows)."""
    if cell.kind == "accuracy":
        return run_accuracy_cell(cell, device)
    if cell.kind == "scene":
        return run_scene_cell(cell, device, out_dir)
    raise ValueError(f"cell {cell.id}: unknown kind {cell.kind!r}")


def run_accuracy_cell(cell: Cell, device: str) -> Outcome:
    """One setting of fracture_gs.paper.accuracy through its case function."""
    from ..paper import accuracy

    p = cell.params
    result = accuracy.CASES[p["case"]](1.0 / p["cells"], p["cfl"], device, cell.labels[0])
    metrics = {
        "dt": result.dt,
        "particles": result.particles,
        "substeps": result.substeps,
        "wall_s": result.wall_s,
        "error": result.error,
        "unit": result.unit,
        "detail": result.detail,
    }
    metrics.update({k: v for k, v in result.extra.items() if v is None or isinstance(v, (bool, int, float, str))})
    return Outcome(metrics)


def _flat(summary: dict) -> tuple[dict, dict]:
    """render-sim's per-variant summary → (flat metrics, nested extras)."""
    flat, extra = {}, {}
    for key, value in summary.items():
        if key in ("variant", "status", "interrupted"):
            continue
        if isinstance(value, dict):
            extra[key] = value
        elif isinstance(value, (list, tuple)):
            extra[key] = list(value)
        else:
            flat[key] = value
    latch = summary.get("latch") or {}
    flat["latch_frame"] = latch.get("latch_frame")
    flat["latch_time"] = latch.get("latch_time")
    return flat, extra


def run_scene_cell(cell: Cell, device: str, out_dir: Optional[Path] = None) -> Outcome:
    """One config × variant × settings: simulate without rendering (or with, `render = true`)."""
    import torch

    from .. import assets
    from ..io.config import config_from_dict
    from ..pipeline import make_simulator, prepare_scene, simulate
    from ..render_sim import summarize
    from ..sim import SimulationDiverged

    cfg = config_from_dict(cell.config, source=f"sweep cell {cell.id}")
    variant, seed = cell.params["variant"], int(cell.params["seed"])
    if cell.params.get("render"):
        from ..render_sim import run_render_sim

        folder = Path(out_dir if out_dir is not None else ".") / "cells" / cell.id
        run = run_render_sim(cfg, [variant], device, folder, progress=False)
        flat, extra = _flat(run.variants[0])
        flat["particles"] = run.particles
        flat["frames"] = cfg.frames
        return Outcome(flat, run.variants[0].get("status", "ok"), extra)
    torch.manual_seed(seed)
    if cfg.scene in assets.names():
        gs = assets.build(cfg.scene, size=cfg.preset, n=cfg.particles, seed=seed).to(device)
    else:
        scene = prepare_scene(cfg, device)
        cfg, gs = scene.cfg, scene.gaussians
    sim = make_simulator(cfg, gs, variant, device)
    cov0 = gs.covariances().to(device, torch.float32)
    rows, status = [], "ok"
    _sync(device)
    t0 = time.perf_counter()
    try:
        for out in simulate(sim, cov0, cfg.frames, cfg.frame_dt, carrier=gs.carrier):
            rows.append(out.metrics)
    except SimulationDiverged as err:
        status = f"diverged at frame {err.frame}: {err.cause or err}"
    _sync(device)
    summary = summarize(variant, rows, status, time.perf_counter() - t0)
    flat, extra = _flat(summary.as_dict())
    flat["particles"] = len(gs)
    flat["frames"] = cfg.frames
    flat["dt"] = float(sim.dt) if math.isfinite(float(sim.dt)) else None
    return Outcome(flat, status, extra)


def warmup(device: str) -> None:
    """Compile and load the solver's kernels (fracture_gs.paper.accuracy.warmup: a tiny bar and a
    re-contact run) so that no cell's wall time includes it."""
    from ..paper import accuracy

    accuracy.warmup(device)
