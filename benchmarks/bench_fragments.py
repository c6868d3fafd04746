"""Table 2 extended with K fragments: the ficus shattered into K Voronoi pieces, Shared field against
FractureFields, time per transfer substep and grid memory.

    python benchmarks/bench_fragments.py --device cuda:0                     # 171,553 particles, 128³
    python benchmarks/bench_fragments.py --device cpu --particles 3000 --n 32  # a smoke run
    python benchmarks/bench_fragments.py --device cuda:0 --storage boxes     # FractureFields in per-fragment boxes only

Scope as the paper's Table 2: grid reset, P2G, grid update (normalization, contact, boundaries), G2P (no
stress, diagnostics or rendering). The state is `fracture_gs.paper.fragments`' (contact along mass-gradient
normals for every K: Voronoi faces have no one latched plane). FractureFields runs in each grid storage of
`--storage` (the simulator's `sim.grid_storage`: slots, boxes). Each branch runs on its own copy of one
latched state; on CUDA the substep is a recorded graph timed with CUDA events (medians over `--steps` after
warm-up). Every branch is built `--placements` times on fresh memory shifted by a random pad, and every trial
times all builds of all branches round-robin, so a host drifting during the run moves Shared and FractureFields
alike (until the tenth session each branch was timed in a block of its own, and the K = 16 ratio moved with
the host between the blocks: docs/benchmarks/history-2026-11.md). Memory: the grid
buffers as allocated (slots: dense slot 0, owner words, the pool of multi-fragment nodes sized for the state,
and beside them the slot cache of the GPU's fan-out, a buffer index per (particle that is not solo, stencil
node); boxes: the dense grid the simulator keeps for the time before a latch plus the boxes' buffers).
"""

from __future__ import annotations

import argparse
import copy
import gc
import json
import statistics
import sys
import time

import torch
import warp as wp

from fracture_gs.paper.bench import placement_pad
from fracture_gs.paper.fragments import shattered_state as state
from fracture_gs.paper.fragments import voronoi_topology as topology
from fracture_gs.runtime import warp_stream
from fracture_gs.sim import Simulator
from fracture_gs.sim.storage import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW

BRANCHES = (("Shared", "stress_zero", "slots"), ("FractureFields", "full", "slots"), ("Boxes", "full", "boxes"))


def build(cfg, P, topo, variant, device, sort="cell", storage="slots"):
    c = copy.deepcopy(cfg.sim)
    c.variant, c.grid_storage = variant, storage
    sim = Simulator(c, P.clone(), device=device)
    sim.record_contact = False
    sim.latch(topo)
    if sort != "built":  # the same order for every branch (cell: by cell, then fragment; P2G in runs on a GPU)
        sim.sort_particles(sort)
    sim.fit_active_box(0.05)
    sim.set_clock(c.dt)
    with sim._stream_scope():
        sim.transfer()  # sizes nothing: the pool came from the latch's estimate; count what it needs
    rows = int(sim.grid.rows_used())
    sim.slots.pool_rows = rows
    sim.fit_active_box(0.05)  # a pool sized from the state's own rows, as between frames
    return sim


def time_builds(sims: list, steps: int, warmup: int, trials: int) -> list[list[float]]:
    """Median ms of a transfer for each build in `sims`, per trial: every trial times all builds round-robin
    (every branch's placements interleaved), so a host or clock drifting during the run moves every branch alike
    and not only the one timed last."""
    cuda = sims[0].device.startswith("cuda")
    graphs = []
    for sim in sims:
        for _ in range(warmup):
            with sim._stream_scope():
                sim.transfer()
        if cuda:
            with sim._stream_scope():
                with wp.ScopedCapture(
                    device=sim.device, stream=warp_stream(sim.device), force_module_load=False
                ) as cap:
                    sim.transfer()
            graphs.append(cap.graph)
        else:
            graphs.append(None)
    samples = [[] for _ in sims]
    for _ in range(trials):
        for sim, graph, out in zip(sims, graphs, samples):
            gc.disable()
            try:
                ms = []
                for _ in range(steps):
                    if cuda:
                        a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
                        with sim._stream_scope():
                            a.record()
                            wp.capture_launch(graph, stream=warp_stream(sim.device))
                            b.record()
                        b.synchronize()
                        ms.append(a.elapsed_time(b))
                    else:
                        t = time.perf_counter()
                        sim.transfer()
                        ms.append(1e3 * (time.perf_counter() - t))
                out.append(statistics.median(ms))
            finally:
                gc.enable()
    return samples


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--device", default="cuda:0" if torch.cuda.is_available() else "cpu")
    p.add_argument("--particles", type=int, default=None, help="default: the paper's 171,553")
    p.add_argument("--n", type=int, default=128, help="grid cells per axis")
    p.add_argument("--K", default="2,4,8,16")
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument("--trials", type=int, default=3)
    p.add_argument("--placements", type=int, default=3)
    p.add_argument(
        "--sort", choices=("cell", "interleaved", "built"), default="cell", help="particle order (default cell)"
    )
    p.add_argument(
        "--storage",
        default="slots,boxes",
        help="FractureFields' grid storages to time (sim.grid_storage), comma-separated (default slots,boxes)",
    )
    a = p.parse_args(argv)
    if a.device.startswith("cuda"):  # graph capture needs a non-default stream
        torch.cuda.set_stream(torch.cuda.Stream(a.device))
    else:
        a.steps, a.warmup, a.placements = min(a.steps, 10), min(a.warmup, 2), 1
    cfg, P = state(a.particles, a.device, a.n)
    rows = []
    for K in (int(k) for k in a.K.split(",")):
        topo = topology(P, K, cfg.sim.dx)
        out = {"K": K}
        storages = a.storage.split(",")
        branches = [b for b in BRANCHES if b[1] != "full" or b[2] in storages]
        rng = torch.Generator().manual_seed(0)
        labels, sims, pads = [], [], []
        for _ in range(a.placements):  # each build on fresh memory, shifted by a random pad (paper.bench's way)
            for label, variant, storage in branches:
                if a.device.startswith("cuda"):
                    pads.append(placement_pad(rng, a.device))
                labels.append(label)
                sims.append(build(cfg, P, topo, variant, a.device, a.sort, storage))
        samples = time_builds(sims, a.steps, a.warmup, a.trials)
        for label, _variant, storage in branches:
            mine = [i for i, name in enumerate(labels) if name == label]
            ms = [m for i in mine for m in samples[i]]
            first = sims[mine[0]]
            first.counts.zero_()  # the overflow and escape counts of one substep
            with first._stream_scope():
                first.transfer()
            out[label] = {
                "median_ms": statistics.median(ms),
                "min_ms": min(ms),
                "max_ms": max(ms),
                "samples_ms": ms,  # placement-major: placement j's trials, then placement j + 1's
                "grid_mib": first.grid_nbytes / 2**20,
                # the slot storage's fan-out cache beside its grid (boxes have none)
                "slot_cache_mib": (
                    first.slots.slot_cache.numel() * 4 / 2**20 if first.options.fanout and storage == "slots" else 0.0
                ),
                "pool_rows": int(first.grid.rows_used()),
                "slot_overflow": int(first.counts[COUNT_SLOT_OVERFLOW]),
                "escaped": int(first.counts[COUNT_ESCAPED]),
            }
        del sims, pads
        for label in ("FractureFields", "Boxes"):
            if label in out:
                ff = out[label]
                out[label]["time_ratio"] = ff["median_ms"] / out["Shared"]["median_ms"]
                out[label]["memory_ratio"] = (ff["grid_mib"] + ff["slot_cache_mib"]) / out["Shared"]["grid_mib"]
                # each sample over the Shared sample timed just before it (same trial, same placement)
                out[label]["paired_ratio"] = statistics.median(
                    f / s for f, s in zip(ff["samples_ms"], out["Shared"]["samples_ms"])
                )
        rows.append(out)
        print(json.dumps(out), flush=True)
    dev = torch.cuda.get_device_name(a.device) if a.device.startswith("cuda") else "cpu"
    print(f"\n### K fragments ({dev}, {len(P)} particles, {a.n}³, {a.sort} order)\n")
    print("| K | Shared ms | FractureFields storage | ms | × Shared | × Shared, paired | MiB (with slot cache) | "
          "× Shared's | escaped / substep | overflow / substep |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        for label, storage in (("FractureFields", "slots"), ("Boxes", "boxes")):
            if label in r:
                f = r[label]
                print(
                    f"| {r['K']} | {r['Shared']['median_ms']:.4f} | {storage} | {f['median_ms']:.4f} | "
                    f"{f['time_ratio']:.3f} | {f['paired_ratio']:.3f} | "
                    f"{f['grid_mib'] + f['slot_cache_mib']:.1f} | {f['memory_ratio']:.3f} | "
                    f"{f['escaped']} | {f['slot_overflow']} |"
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
