"""The K-fragment experiment (issue "many pieces"): the ficus shattered into K Voronoi pieces, Shared Field
against FractureFields in per-fragment boxes, time per transfer substep and grid memory (as Table 2), then
the pieces pressed into each other for a few frames: deepest depth of a particle behind another piece's
surface (continuous, `sim.penetration.surface_depth`) beside the voxel-occupancy depth (steps of 0.6Δx), the
contact projection's momentum residual and the slot overflows. `fragments_table` is the figures script's table;
`benchmarks/bench_fragments.py` times both grid storages with the same state.
"""

from __future__ import annotations

import contextlib
import copy
import platform

import torch

from ..runtime import side_stream
from ..sim import Particles, Simulator, Topology
from ..sim.providers.cuts import voronoi_labels
from ..sim.providers.voronoi import voronoi_sites
from .bench import bench_state, time_branches
from .tables import Column, Panel, Table

KS = (2, 4, 8, 16)
PRESS_SPEED = 0.5  # m/s: every piece driven toward the ficus' centroid at most this fast
PRESS_FRAME = 0.004  # s


def shattered_state(particles, device: str, n: int):
    """Table 2's ficus (`bench.bench_state`: `particles`, default the paper's 171,553, in n³ with Δx = 1/n),
    with contact along mass-gradient normals for every K: Voronoi faces have no one latched plane."""
    cfg, P, _ = bench_state(particles, device, n)
    cfg.sim.contact.normal = "mass_gradient"
    return cfg, P


def voronoi_topology(P: Particles, K: int, dx: float) -> Topology:
    """K Voronoi cells (sites drawn from the particles, seed 0), band 1.5Δx around the cell faces."""
    fragment, band = voronoi_labels(P.x, voronoi_sites(P.x, K, 0), 1.5 * dx)
    return Topology(fragment=fragment, band=band, normal=(0.0, 0.0, 1.0), point=(0.5, 0.5, 0.4))


def pressed(cfg, P: Particles, topo: Topology, device: str, frames: int, storage: str = "boxes") -> dict:
    """The pieces driven toward the centroid (no gravity) for `frames` frames of FractureFields: the run's
    deepest depth behind another piece's surface [Δx], deepest voxel-occupancy depth [Δx], largest contact
    momentum residual, contact nodes and slot overflows (from the diagnostics' rows)."""
    c = copy.deepcopy(cfg.sim)
    c.variant, c.grid_storage, c.gravity, c.adaptive_dt = "full", storage, (0.0, 0.0, 0.0), True
    sim = Simulator(c, P.clone(), device=device)
    sim.latch(topo)
    Q = sim.particles
    d = Q.x.mean(0) - Q.x
    Q.v.copy_(PRESS_SPEED * d / d.norm(dim=1).max().clamp_min(1e-12))
    tracker = sim.diagnostics_tracker()
    for _ in range(frames):
        sim.advance(PRESS_FRAME)
    rows = tracker.history
    return {
        "penetration": max(float(r.get("fragment_penetration", 0.0)) for r in rows),
        "voxel_penetration": max(float(r.get("voxel_penetration", 0.0)) for r in rows),
        "residual": max(float(r.get("cp_momentum_residual", 0.0)) for r in rows),
        "contact_nodes": sum(float(r.get("contact_nodes", 0.0)) for r in rows),
        "overflow": int(sim.slot_overflow_total),
    }


def fragment_rows(device: str, particles=None, n: int = 128, Ks=KS, steps=200, warmup=20, trials=3, frames=10):
    """One row per K: timing and memory of both branches (as Table 2), then the pressed run."""
    cfg, P = shattered_state(particles, device, n)
    cuda = device.startswith("cuda")
    branches = [("Shared", "stress_zero", "slots"), ("FractureFields", "full", "boxes")]
    stream = side_stream(device) if cuda else None  # graph capture needs a stream other than the default
    rows = []
    for K in Ks:
        topo = voronoi_topology(P, K, cfg.sim.dx)
        with torch.cuda.stream(stream) if cuda else contextlib.nullcontext():
            shared, ff = time_branches(
                cfg, P, topo, device, steps, warmup, trials, graph=cuda, placements=2 if cuda else 1, branches=branches
            )
        row = {
            "K": K,
            "shared_ms": shared["median_ms"],
            "ff_ms": ff["median_ms"],
            "time_ratio": ff["median_ms"] / shared["median_ms"],
            "shared_mib": shared["grid_mib"],
            "ff_mib": ff["grid_mib"],
            "memory_ratio": ff["grid_mib"] / shared["grid_mib"],
        }
        row.update(pressed(cfg, P, topo, device, frames))
        rows.append(row)
    return rows, len(P), n


def fragments_table(device: str, protocol: str, command: str = "") -> Table:
    """K against time, memory, penetration, momentum residual and overflow (the quick protocol: 4,000
    particles in 32³, a few timed substeps; the paper protocol: 171,553 in 128³)."""
    cuda = device.startswith("cuda")
    paper = protocol == "paper"
    rows, particles, n = fragment_rows(
        device,
        None if paper else 4000,
        128 if paper else 32,
        steps=200 if cuda else 5,
        warmup=20 if cuda else 1,
        trials=3 if cuda else 1,
        frames=10 if paper else 5,
    )
    cols = [
        Column("K", "K", "$K$", "int"),
        Column("shared_ms", "Shared (ms)", "Shared (ms)", "num"),
        Column("ff_ms", "FractureFields (ms)", "FractureFields (ms)", "num"),
        Column("time_ratio", "× Shared", r"$\times$ Shared", "num"),
        Column("ff_mib", "Grid MiB", "Grid MiB", "num"),
        Column("memory_ratio", "× Shared's", r"$\times$ Shared's", "num"),
        Column("penetration", "Max depth behind surface/Δx", r"Max depth/$\Delta x$", "num"),
        Column("voxel_penetration", "Voxel pen./Δx", r"Voxel pen./$\Delta x$", "num"),
        Column("residual", "Momentum residual", "Momentum residual", "sci"),
        Column("contact_nodes", "Contact nodes", "Contact nodes", "int"),
        Column("overflow", "Overflow", "Overflow", "int"),
    ]
    name = torch.cuda.get_device_name(torch.device(device)) if cuda else (platform.processor() or "CPU")
    caption = (
        f"The ficus ({particles} particles, {n}³, Δx = 1/{n}) shattered into K Voronoi pieces (seed 0). Time and "
        f"memory as Table 2 (transfer substep; FractureFields in per-fragment boxes, `sim.grid_storage = "
        f'"boxes"`; grid memory includes the dense grid kept for the time before a latch) on {name}'
        + ("" if cuda else ", wall clock of Warp's single-threaded CPU kernels, indicative only")
        + f". Then every piece is driven toward the centroid at up to {PRESS_SPEED} m/s for the frames of "
        f"{PRESS_FRAME} s: the deepest depth of a particle behind another piece's surface (estimated continuously "
        f"from that piece's particles, a kernel volume fraction over 6 particle spacings, each piece weighed by its "
        f"own number density at the latch; jittered blocks pushed by a known depth read it within 0.05Δx), "
        f"the voxel-occupancy depth (0.6Δx voxels eroded once: it reads in steps of 0.6Δx, so one voxel is its "
        f"floor, not the physics), the contact projection's largest relative momentum residual, "
        f"contact nodes summed over frames, "
        f"and fields left uncoupled at nodes holding more "
        f"than `sim.field_slots` fields (overflow, summed over substeps)."
    )
    return Table(
        "table_fragments",
        "K fragments: time, memory and contact",
        [Panel(cols, rows)],
        caption,
        "tab:fragments",
        command,
    )
