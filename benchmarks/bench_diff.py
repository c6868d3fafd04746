"""Cost of gradients through the simulation: forward and backward time of one substep, and memory.

    python benchmarks/bench_diff.py --device cuda:0                 # ficus at the paper's 171,553 particles
    python benchmarks/bench_diff.py --device cpu --particles 3000   # a smoke run

Times one frame of `DiffSimulator` (n substeps) forward (no tape) and backward (the frame recomputed
under a wp.Tape, then the adjoints), reports per-substep milliseconds, their ratio, the frame's
checkpoint (bytes per particle) and the peak device memory of the backward pass: torch's allocator
(autograd, the float32 copies handed to Warp) plus Warp's memory pool (the tape's per-substep buffers
and their adjoints), each as a high-water mark over the run minus what was held before it.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import torch
import warp as wp

from fracture_gs import assets
from fracture_gs.config import SceneConfig
from fracture_gs.sim import Particles, Topology
from fracture_gs.sim.diff import DiffSimulator


def sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize(device)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--device", default="cuda:0" if torch.cuda.is_available() else "cpu")
    p.add_argument("--particles", type=int, default=None, help="default: the paper's 171,553")
    p.add_argument("--substeps", type=int, default=10, help="substeps per timed frame")
    p.add_argument("--repeats", type=int, default=7)
    a = p.parse_args(argv)
    dev = a.device
    gs = assets.build("ficus", size="paper", n=a.particles)
    cfg = SceneConfig(scene="ficus")
    cfg.sim.dx, cfg.sim.grid_shape, cfg.sim.dt, cfg.sim.variant = 1 / 128, (128, 128, 128), 2e-5, "full"
    cfg.material.E, cfg.material.density = 2e6, 200.0
    P = Particles.from_gaussians(gs, cfg, dx=cfg.sim.dx).to(dev)
    topo = Topology.from_plane(P.x, (0.5, 0.5, 0.35), (0.0, 0.0, 1.0), 1 / 128)
    sim = DiffSimulator(cfg.sim, P.x, dev, topologies=[topo])
    mu = (P.E / (2 * (1 + P.nu))).requires_grad_()
    lam = (P.E * P.nu / ((1 + P.nu) * (1 - 2 * P.nu))).requires_grad_()
    x, v = P.x.clone().requires_grad_(), P.v.clone().requires_grad_()
    C, F = P.C.clone().requires_grad_(), P.F.clone().requires_grad_()
    frame_dt = a.substeps * cfg.sim.dt
    cuda = dev.startswith("cuda")
    warp_base = wp.get_mempool_used_mem_current(dev) if cuda else 0
    rows = []
    for _ in range(a.repeats + 1):
        sim.frame, sim.time, sim.plans = 0, 0.0, []
        sync(dev)
        t0 = time.perf_counter()
        out = sim.step(frame_dt, x, v, C, F, mu, lam, P.mass, P.volume)
        sync(dev)
        t1 = time.perf_counter()
        if dev.startswith("cuda"):
            torch.cuda.reset_peak_memory_stats(dev)
            base = torch.cuda.memory_allocated(dev)
        loss = (out[0] ** 2).sum() + (out[3] ** 2).sum()
        loss.backward()
        sync(dev)
        t2 = time.perf_counter()
        peak = (torch.cuda.max_memory_allocated(dev) - base) if dev.startswith("cuda") else None
        n = sim.plans[-1].n
        rows.append(
            {
                "forward_ms_per_substep": 1e3 * (t1 - t0) / n,
                "backward_ms_per_substep": 1e3 * (t2 - t1) / n,
                "peak_backward_MiB": None if peak is None else peak / 2**20,
            }
        )
    rows = rows[1:]  # the first repeat compiles
    med = {k: sorted(r[k] for r in rows)[len(rows) // 2] if rows[0][k] is not None else None for k in rows[0]}
    warp_peak = (wp.get_mempool_used_mem_high(dev) - warp_base) / 2**20 if cuda else None
    n_particles = len(P)
    checkpoint = 4 * (3 + 3 + 9 + 9)  # x, v, C, F in float32 at each frame's start
    result = {
        "device": torch.cuda.get_device_name(dev) if dev.startswith("cuda") else "cpu",
        "particles": len(P),
        "grid": 128,
        "substeps_per_frame": a.substeps,
        "warp_pool_release_threshold_MiB": wp.get_mempool_release_threshold(dev) / 2**20 if cuda else None,
        **med,
        "backward_over_forward": med["backward_ms_per_substep"] / med["forward_ms_per_substep"],
        "backward_over_forward_per_repeat": [
            round(r["backward_ms_per_substep"] / r["forward_ms_per_substep"], 3) for r in rows
        ],
        "warp_peak_MiB": warp_peak,
        "backward_peak_bytes_per_particle": None
        if warp_peak is None
        else (med["peak_backward_MiB"] + warp_peak) * 2**20 / n_particles,
        "checkpoint_bytes_per_particle": checkpoint,
        "checkpoint_MiB_per_frame": checkpoint * n_particles / 2**20,
    }
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
