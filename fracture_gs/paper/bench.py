"""Transfer benchmarks: the baseline substep by phase and the paper's Table 2 branches.

    fracture-gs bench --device cuda:0                 # full table, writes BENCHMARKS-run.md
    fracture-gs bench --device cpu --particles 20000  # a CPU smoke run
    fracture-gs bench --accuracy                      # speed against error (fracture_gs.paper.accuracy)

Scope of Table 2 (as in the paper): grid reset, P2G, normalization (+ contact), G2P; stress,
probing, diagnostics and rendering excluded. All branches run on the same latched particle state
(the built-in ficus at the paper's 171,553 particles in a 128³ grid, Δx = 1/128). On CUDA each
trial is a median of CUDA-event intervals over ≥ 200 substeps after warm-up; each branch is built
on fresh device memory several times (`--placements`) and trials run round-robin over all builds,
so neither where the allocator put a branch's grid nor clock drift decides the comparison. A
per-kernel breakdown (CUDA profiler) comes with it. Last, the whole substep (stress + transfer) of the
baseline and of FractureFields after the cut, built and timed the same way, and their ratio (issue 13's
"FractureFields ≤ 1.05× the baseline substep"). On the CPU: wall-clock medians (marked as CPU).
"""

from __future__ import annotations

import datetime
import gc
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import torch
import warp as wp

from .. import assets
from ..config import SceneConfig, SimConfig
from ..runtime import capture_lock, ensure_warp, side_stream, warp_stream
from ..sim import Particles, Simulator, Topology
from ..variants import variant_spec

WHOLE = [  # issue 13: FractureFields' whole substep after the cut against the baseline's, the same builds
    ("baseline", "baseline"),
    ("FractureFields", "full"),  # sim.grid_storage = "auto": per-fragment boxes
    ("FractureFields (slots)", "full", "slots"),  # the slot storage, for comparison
]
BRANCHES = [  # (Table 2 row, variant[, sim.grid_storage]); the passes column is the variant's `VariantSpec.passes`
    ("Shared Field", "stress_zero"),
    ("Global Fragment Pass", "global_fragment_pass"),
    ("Local Multi-Field", "local_multifield"),
    ("FractureFields", "full"),
]


def bench_state(particles: int | None, device: str, n: int = 128, shuffle: bool = False):
    """The ficus at `particles` (default: the paper's 171,553) with a latched plane through the trunk."""
    gs = assets.build("ficus", size="paper", n=particles)
    cfg = SceneConfig(scene="ficus")
    # Δt = 2e-5 s at Δx = 1/128: under the CFL bound 0.4·Δx/c ≈ 2.7e-5 s for E = 2e6, ρ = 200 (∝ Δx)
    cfg.sim = SimConfig(
        dx=1.0 / n, grid_shape=(n, n, n), grid_origin=(0.0, 0.0, 0.0), dt=2e-5 * 128 / n, gravity=(0.0, 0.0, -9.8)
    )
    cfg.material.E, cfg.material.density = 2e6, 200.0
    P = Particles.from_gaussians(gs, cfg)
    if shuffle:
        P.permute(torch.randperm(len(P)))
    topo = Topology.from_plane(P.x, (0.5, 0.5, 0.40), (0.2, 0.0, 1.0), band_width=1.5 / n)
    return cfg, P, topo


def make_sim(cfg, P, topo, variant, device, sort, storage=None):
    import copy

    sim_cfg = copy.deepcopy(cfg.sim)
    sim_cfg.variant = variant
    sim_cfg.grid_storage = storage or sim_cfg.grid_storage
    sim = Simulator(sim_cfg, P.clone(), device=device)
    sim.record_contact = False  # contact statistics are diagnostics, outside the paper's timing scope
    sim.latch(topo)
    if sort:  # after the latch: by cell, then fragment (P2G's runs break at most once per fragment in a cell)
        sim.sort_particles(sort)
    sim.compute_stress(sim.stress, commit=True)
    sim.fit_active_box(HORIZON)
    sim.set_clock(cfg.sim.dt)
    return sim


HORIZON = 0.05  # s: covers the motion during every timed substep (≤ 1,000 substeps of 2e-5 s)


class Timer:
    """CUDA events on torch's current stream (where Warp launches too), or wall clock on CPU."""

    def __init__(self, device: str):
        self.cuda = device.startswith("cuda")

    def mark(self):
        if self.cuda:
            e = torch.cuda.Event(enable_timing=True)
            e.record()
            return e
        return time.perf_counter()

    def ms(self, a, b) -> float:
        if self.cuda:
            return a.elapsed_time(b)
        return (b - a) * 1e3

    def sync(self):
        if self.cuda:
            torch.cuda.synchronize()


def capture(sim: Simulator, fn):
    """A CUDA graph of `fn` (Warp launches and torch zero_ on the current, non-default stream)."""
    with sim._stream_scope(), capture_lock:
        with wp.ScopedCapture(device=sim.device, stream=warp_stream(sim.device), force_module_load=False) as cap:
            fn()
    return cap.graph


def time_fn(sim: Simulator, fn, steps: int, warmup: int, trials: int, graph: bool) -> list[float]:
    """Per-trial median milliseconds of `fn` (one substep each)."""
    for _ in range(warmup):
        with sim._stream_scope():
            fn()
    g = capture(sim, fn) if graph and sim.device.startswith("cuda") else None
    return [_median_step(sim, fn, g, steps) for _ in range(trials)]


def phase_times(sim: Simulator, dt: float, steps: int, warmup: int) -> dict:
    """Median ms per phase of the baseline substep (stress, P2G incl. reset, grid, G2P)."""
    timer = Timer(sim.device)
    phases = {
        "stress": lambda: sim.compute_stress(sim.stress, commit=True),
        "p2g": lambda: sim.p2g(dt),
        "grid": lambda: sim.update_grid(dt),
        "g2p": lambda: sim.g2p(dt),
    }
    samples = {k: [] for k in phases}
    for i in range(warmup + steps):
        marks = [timer.mark()]
        with sim._stream_scope():
            for fn in phases.values():
                fn()
                marks.append(timer.mark())
        timer.sync()
        if i >= warmup:
            for (k, _), a, b in zip(phases.items(), marks, marks[1:]):
                samples[k].append(timer.ms(a, b))
    out = {k: statistics.median(v) for k, v in samples.items()}
    out["total"] = sum(out.values())
    return out


KERNEL_PHASES = {
    "clear_dense": "reset",
    "clear_pool": "reset",
    "p2g": "p2g",
    "p2g_fanout": "p2g",
    "p2g_runs": "p2g",
    "grid_update_dense": "grid",
    "grid_update_pool": "grid",
    "pool_mass_gradients": "grid",
    "g2p": "g2p",
    "g2p_fanout": "g2p",
    "box_clear": "reset",
    "box_p2g_runs": "p2g",
    "box_p2g_runs_band": "p2g",
    "box_grid_update": "grid",
    "box_grid_update_quiet": "grid",
    "box_grid_update_fast": "grid",
    "box_grid_update_fast_quiet": "grid",
    "box_grid_update_fast_n0": "grid",
    "box_grid_update_fast_quiet_n0": "grid",
    "box_g2p": "g2p",
}
"""Warp kernel name -> Table 2 phase (the transfer kernels of sim/grid/kernels.py, run_kernels.py,
fanout_kernels.py and, for the per-fragment boxes, sim/boxes/kernels.py)."""


def kernel_times(sim: Simulator, dt: float, steps: int = 50) -> dict | None:
    """Device microseconds per substep of each transfer kernel (reset, P2G, grid, G2P), from the
    CUDA profiler (CUPTI sees Warp's launches too); None on the CPU, where it cannot see them."""
    if not sim.device.startswith("cuda"):
        return None
    from torch.profiler import ProfilerActivity, profile

    with sim._stream_scope():
        for _ in range(5):
            sim.transfer()
    torch.cuda.synchronize()
    with profile(activities=[ProfilerActivity.CUDA]) as prof:
        with sim._stream_scope():
            for _ in range(steps):
                sim.transfer()
        torch.cuda.synchronize()
    us = dict.fromkeys(KERNEL_PHASES.values(), 0.0)
    for ev in prof.events():
        name = ev.name.split("_cuda_kernel")[0].rsplit("_", 1)[
            0
        ]  # Warp names kernels <name>_<hash>_cuda_kernel_forward
        if ev.device_type.name == "CUDA" and name in KERNEL_PHASES:
            us[KERNEL_PHASES[name]] += ev.device_time / steps  # profiler times are in µs
    return us


def placement_pad(rng: torch.Generator, device: str) -> torch.Tensor:
    """1–63 MiB of device memory, held while the next build allocates, so that builds of one branch land at
    different addresses (P2G's atomics resolve in L2, whose slices the address picks)."""
    return torch.empty(int(torch.randint(1, 64, (), generator=rng)) << 20, dtype=torch.uint8, device=device)


def time_branches(
    cfg,
    P,
    topo,
    device: str,
    steps=200,
    warmup=20,
    trials=3,
    graph=True,
    sort="cell",
    placements: int = 1,
    seed: int = 0,
    branches: list | None = None,
    whole: bool = False,
) -> list[dict]:
    """Table 2 rows: median ms, relative to the first branch (Shared), grid-buffer MiB, passes, kernel µs.
    `branches` (label, variant[, grid storage]) default to Table 2's; `whole` times the whole substep (stress and
    transfer, issue 13's comparison of FractureFields with the baseline) instead of the transfer, without
    the kernel columns.

    Each branch is built `placements` times, every build on fresh device memory shifted by a
    random pad: on a GPU, allocations of the same branch and state differ in time by more than the
    branches do (P2G's atomics resolve in L2, whose slices the address picks; BENCHMARKS.md).
    Every trial then times all builds round-robin, so clock drift hits all branches alike. A
    branch's time is the median over builds × trials."""
    dt = cfg.sim.dt
    cuda = device.startswith("cuda")
    rng = torch.Generator().manual_seed(seed)
    builds, keep = [], []
    branches = BRANCHES if branches is None else branches
    for rep in range(placements):
        for label, variant, *storage in branches:
            if cuda:  # shift where the next build's buffers land
                keep.append(placement_pad(rng, device))
            sim = make_sim(cfg, P, topo, variant, device, sort, *storage)
            fn = (lambda s=sim: (s.compute_stress(s.stress, commit=True), s.transfer())) if whole else sim.transfer
            for _ in range(warmup):
                with sim._stream_scope():
                    fn()
            g = capture(sim, fn) if graph and cuda else None
            builds.append(
                {
                    "label": label,
                    "variant": variant,
                    "sim": sim,
                    "fn": fn,
                    "graph": g,
                    "kernels": kernel_times(sim, dt) if rep == 0 and not whole else None,
                }
            )
    samples = {b[0]: [] for b in branches}
    for _ in range(trials):
        for b in builds:
            samples[b["label"]].append(_median_step(b["sim"], b["fn"], b["graph"], steps))
    rows = []
    for label, variant, *_ in branches:
        first = next(b for b in builds if b["label"] == label)
        ms = samples[label]
        rows.append(
            {
                "branch": label,
                "variant": variant,
                "passes": variant_spec(variant).passes,
                "median_ms": statistics.median(ms),
                "min_ms": min(ms),
                "max_ms": max(ms),
                "samples_ms": ms,
                "placements": placements,
                "grid_mib": first["sim"].grid_nbytes / 2**20,
                "kernels_us": first["kernels"],
            }
        )
    del builds, keep
    if cuda:
        torch.cuda.empty_cache()
    base = rows[0]["median_ms"]
    for r in rows:
        r["relative"] = r["median_ms"] / base
    return rows


def _median_step(sim: Simulator, fn, graph, steps: int) -> float:
    """Median milliseconds of one substep over `steps` (graph replays where captured), with the
    garbage collector paused as `timeit` does: a collection inside a long-running process (the
    figures script) otherwise lands in the CPU wall-clock samples."""
    timer = Timer(sim.device)
    gc.collect()
    gc.disable()
    try:
        marks = [timer.mark()]
        for _ in range(steps):
            with sim._stream_scope():
                wp.capture_launch(graph, stream=warp_stream(sim.device)) if graph is not None else fn()
            marks.append(timer.mark())
        timer.sync()
    finally:
        gc.enable()
    return statistics.median(timer.ms(a, b) for a, b in zip(marks, marks[1:]))


def baseline_rows(cfg, P, topo, device, steps, warmup, trials, graph) -> list[dict]:
    """The whole baseline substep (stress + transfer) under each optimization, and its phases."""
    rows = []
    dt = cfg.sim.dt
    settings = [
        ("as built", None, False, False),
        ("random order", "random", False, False),
        ("cell order (P2G in runs on a GPU)", "cell", False, False),
        ("interleaved cell order", "interleaved", False, False),
        ("interleaved + active box", "interleaved", False, True),
        ("interleaved + CUDA graph", "interleaved", True, False),
        ("interleaved + active box + CUDA graph", "interleaved", True, True),
        ("cell order + P2G runs + active box + CUDA graph", "cell", True, True),
    ]
    for label, sort, use_graph, box in settings:
        if use_graph and not (graph and device.startswith("cuda")):
            continue
        sim = Simulator(_variant(cfg.sim, "baseline"), P.clone(), device=device)
        sim.set_clock(dt)
        if sort == "random":
            sim.particles.permute(torch.randperm(len(sim.particles), device=sim.particles.x.device))
        elif sort:
            sim.sort_particles(sort)
        if box:
            sim.fit_active_box(HORIZON)

        def step(sim=sim):
            sim.compute_stress(sim.stress, commit=True)
            sim.transfer()

        ms = time_fn(sim, step, steps, warmup, trials, use_graph)
        row = {"setting": label, "median_ms": statistics.median(ms), "trials_ms": ms}
        if not use_graph:
            row["phases"] = phase_times(sim, dt, min(steps, 100), warmup)
        rows.append(row)
    return rows


def _nullcontext():
    import contextlib

    return contextlib.nullcontext()


def _variant(sim_cfg, variant):
    import copy

    c = copy.deepcopy(sim_cfg)
    c.variant = variant
    return c


def markdown(result: dict) -> str:
    env = result["env"]
    lines = [
        f"### {env['date']} — {env['device_name']} ({result['particles']} particles, grid {result['grid']}³)",
        "",
        f"Command: `{env['command']}`",
        "",
        "Baseline substep (stress + reset + P2G + grid + G2P):",
        "",
        "| setting | median (ms) | stress | P2G | grid | G2P |",
        "|---|---|---|---|---|---|",
    ]
    for r in result["baseline"]:
        ph = r.get("phases")
        cells = [f"{ph[k]:.4f}" for k in ("stress", "p2g", "grid", "g2p")] if ph else ["—"] * 4
        lines.append(f"| {r['setting']} | {r['median_ms']:.4f} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"Table 2 (scope: grid reset, P2G, normalization, contact, G2P; {result['sort']} order, active box"
        + (", CUDA graph" if result["graph"] else "")
        + f"; median over {result['placements']} build(s) × "
        f"{result['trials']} trial(s), each a median of {result['steps']} substeps):",
        "",
        "| Branch | Passes (P2G/G2P/frag) | Median (ms) | Relative | Range (ms) | Grid-buffer footprint (MiB) "
        "| reset µs | P2G µs | grid µs | G2P µs |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["table2"]:
        k = r.get("kernels_us")
        cells = [f"{k[p]:.1f}" for p in ("reset", "p2g", "grid", "g2p")] if k else ["—"] * 4
        lines.append(
            f"| {r['branch']} | {r['passes']} | {r['median_ms']:.4f} | {r['relative']:.3f} | "
            f"{r['min_ms']:.4f}–{r['max_ms']:.4f} | {r['grid_mib']:.1f} | " + " | ".join(cells) + " |"
        )
    if result["table2"][0].get("kernels_us"):
        lines += [
            "",
            "Kernel columns: device µs per substep from the CUDA profiler on the first build, plain launches.",
        ]
    if result.get("whole"):
        base, *ffs = result["whole"]
        ff = "; ".join(
            f"{r['branch']} {r['median_ms']:.4f} ms ({r['min_ms']:.4f}–{r['max_ms']:.4f}), **{r['relative']:.2f}×**"
            for r in ffs
        )
        lines += [
            "",
            f"Whole substep (stress + transfer) after the cut, set up as Table 2, the same {result['placements']} "
            f"build(s) × {result['trials']} trial(s): baseline {base['median_ms']:.4f} ms "
            f"({base['min_ms']:.4f}–{base['max_ms']:.4f}); {ff} the baseline.",
        ]
    if not env["device"].startswith("cuda"):
        lines += [
            "",
            "(CPU: Warp runs kernels single-threaded here; wall-clock medians, not comparable with GPU rows.)",
        ]
    return "\n".join(lines) + "\n"


def run_bench(
    device="cuda:0",
    out_dir="runs/bench",
    particles=None,
    steps=200,
    warmup=20,
    trials=3,
    graph=True,
    sort="cell",
    placements=None,
    grid: int = 128,
    command: str | None = None,
) -> dict:
    """Entry point of `fracture-gs bench`: writes bench.json and bench.md into out_dir."""
    ensure_warp()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scfg, P, topo = bench_state(particles, device, n=grid)
    dev_name = (
        torch.cuda.get_device_name(torch.device(device))
        if device.startswith("cuda")
        else platform.processor() or platform.machine() or "CPU"
    )
    if placements is None:
        placements = 5 if device.startswith("cuda") else 1
    result = {
        "particles": len(P),
        "grid": scfg.sim.grid_shape[0],
        "graph": graph and device.startswith("cuda"),
        "sort": sort,
        "placements": placements,
        "trials": trials,
        "steps": steps,
        "env": {
            "device": device,
            "device_name": dev_name,
            "date": datetime.date.today().isoformat(),
            "torch": torch.__version__,
            "warp": wp.config.version,
            "command": command or " ".join(sys.argv),
        },
    }
    # a non-default stream: CUDA graph capture cannot record the legacy default stream
    stream = side_stream(device) if device.startswith("cuda") else None
    with torch.cuda.stream(stream) if stream is not None else _nullcontext():
        result["baseline"] = baseline_rows(scfg, P, topo, device, steps, warmup, trials, graph)
        result["table2"] = time_branches(
            scfg, P, topo, device, steps, warmup, trials, graph=graph, sort=sort, placements=placements
        )
        result["whole"] = time_branches(
            scfg, P, topo, device, steps, warmup, trials, graph, sort, placements, branches=WHOLE, whole=True
        )
    (out_dir / "bench.json").write_text(json.dumps(result, indent=2))
    (out_dir / "bench.md").write_text(markdown(result))
    print(markdown(result))
    return {
        "out_dir": str(out_dir),
        "table2_ms": {r["branch"]: round(r["median_ms"], 4) for r in result["table2"]},
        "whole_ms": {r["branch"]: round(r["median_ms"], 4) for r in result["whole"]},
    }
