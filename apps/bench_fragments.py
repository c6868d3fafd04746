"""Table 2 extended with K fragments: the ficus shattered into K Voronoi pieces, Shared field against
FractureFields, time per transfer substep and grid memory.

    python apps/bench_fragments.py --device cuda:0                     # 171,553 particles, 128³
    python apps/bench_fragments.py --device cpu --particles 3000 --n 32  # a smoke run
    python apps/bench_fragments.py --device cuda:0 --boxes             # also the per-fragment box transfer

Scope as the paper's Table 2: grid reset, P2G, grid update (normalization, contact, boundaries), G2P
(no stress, diagnostics or rendering). Each branch runs on its own copy of one latched state; on CUDA
the substep is a recorded graph timed with CUDA events (medians over `--steps` after warm-up, builds
round-robin over `--placements` fresh allocations, trials round-robin). Memory: the grid buffers as
allocated (dense slot 0, owner words, the pool of multi-fragment nodes sized for the state), and beside
them the slot cache of the GPU's fan-out (a buffer index per (particle that is not solo, stencil node)).
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

from fracture_gs import assets
from fracture_gs.config import SceneConfig, SimConfig
from fracture_gs.runtime import warp_stream
from fracture_gs.sim import Particles, Simulator, Topology
from fracture_gs.sim.boxes import FragmentBoxes
from fracture_gs.sim.layout import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW
from fracture_gs.sim.providers.cuts import voronoi_labels
from fracture_gs.sim.providers.voronoi import voronoi_sites

BRANCHES = (("Shared", "stress_zero"), ("FractureFields", "full"))


def state(particles, device: str, n: int):
    gs = assets.build("ficus", size="paper", n=particles)
    cfg = SceneConfig(scene="ficus")
    cfg.sim = SimConfig(dx=1.0 / n, grid_shape=(n, n, n), dt=2e-5, gravity=(0.0, 0.0, -9.8), max_fragments=64)
    cfg.material.E, cfg.material.density = 2e6, 200.0
    return cfg, Particles.from_gaussians(gs, cfg)


def topology(P: Particles, K: int, dx: float) -> Topology:
    """K Voronoi cells (sites drawn from the particles, seed 0), band 1.5Δx around the cell faces."""
    fragment, band = voronoi_labels(P.x, voronoi_sites(P.x, K, 0), 1.5 * dx)
    return Topology(fragment=fragment, band=band, normal=(0.0, 0.0, 1.0), point=(0.5, 0.5, 0.4))


def build(cfg, P, topo, variant, device, sort="cell"):
    c = copy.deepcopy(cfg.sim)
    c.variant = variant
    sim = Simulator(c, P.clone(), device=device)
    sim.record_contact = False
    if sort != "built":  # the same order for every branch (cell: P2G in runs on a GPU)
        topo = topo.permuted(sim.sort_particles(sort))
    sim.latch(topo)
    sim.fit_active_box(0.05)
    sim.set_clock(c.dt)
    with sim._stream_scope():
        sim.transfer()  # sizes nothing: the pool came from the latch's estimate; count what it needs
    rows = int(sim.grid.rows_used())
    sim.pool_rows = rows
    sim.fit_active_box(0.05)  # a pool sized from the state's own rows, as between frames
    return sim


class BoxTransfer:
    """`--boxes`: the per-fragment box transfer (`fracture_gs.sim.boxes`: clear, P2G, normalization, contact
    where fields meet, G2P) on a built simulator's particles, timed like a simulator's `transfer`. The boxes
    are fitted once, with 2 nodes of slack (stencils that leave them later are counted as escapes)."""

    def __init__(self, sim: Simulator):
        self.sim, self.device = sim, sim.device
        P, g = sim.particles, sim.grid
        self.boxes = FragmentBoxes(g.shape, g.origin, g.dx, sim.device)
        self.boxes.fit(P.x, P.fragment, slack=2)
        K = self.boxes.K
        sums = torch.zeros(K, 3, device=P.x.device).index_add_(0, P.fragment.long().clamp_min(0), P.x)
        count = torch.bincount(P.fragment.long().clamp_min(0), minlength=K).clamp_min(1)
        self.centroids = wp.from_torch((sums / count[:, None]).contiguous(), dtype=wp.vec3)
        self.fill = sim.cfg.contact.fill * sim.node_mass
        self.normal = tuple(float(a) for a in sim._normal)  # the simulator's normals and gate (latched at K = 2)

    def _stream_scope(self):
        return self.sim._stream_scope()

    @property
    def nbytes(self) -> int:
        return self.boxes.nodes * (16 + 12 + 12 + 4)  # (p, m), v, ∇m, the box of each node

    def transfer(self) -> None:
        s, w, dt = self.sim, self.sim.wp, self.sim.cfg.dt
        c = s.cfg.contact
        self.boxes.p2g(w, dt, w["counts"], run=s.p2g_run)  # runs where the simulator uses them (cell order, GPU)
        self.boxes.update(
            dt, s.eps_m, s.cfg.gravity, self.fill, self.centroids, w["counts"], e=float(s.cfg.restitution),
            mu=float(c.friction), latched=self.normal, eps_b=s.eps_b, mass_gradient=s.normal_mode == 1,
            project=s.spec.contact,
        )  # fmt: skip
        self.boxes.g2p(w, dt, s._lower, s._upper, w["counts"])


def time_builds(sims: list, steps: int, warmup: int, trials: int) -> list[float]:
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
    samples = []
    for _ in range(trials):
        for sim, graph in zip(sims, graphs):
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
                samples.append(statistics.median(ms))
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
        "--boxes",
        action="store_true",
        help="also time the per-fragment box transfer (fracture_gs.sim.boxes; docs/DESIGN.md's plan) on the "
        "FractureFields state",
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
        for label, variant in BRANCHES:
            sims = [build(cfg, P, topo, variant, a.device, a.sort) for _ in range(a.placements)]
            ms = time_builds(sims, a.steps, a.warmup, a.trials)
            out[label] = {
                "median_ms": statistics.median(ms),
                "min_ms": min(ms),
                "max_ms": max(ms),
                "grid_mib": sims[0].grid.nbytes / 2**20,
                "slot_cache_mib": sims[0]._slot_cache.numel() * 4 / 2**20 if sims[0].fanout else 0.0,
                "pool_rows": int(sims[0].grid.rows_used()),
                "slot_overflow": int(sims[0].counts[COUNT_SLOT_OVERFLOW]),
            }
            if label == "FractureFields" and a.boxes:
                boxes = [BoxTransfer(s) for s in sims]
                ms = time_builds(boxes, a.steps, a.warmup, a.trials)
                out["Boxes"] = {
                    "median_ms": statistics.median(ms),
                    "min_ms": min(ms),
                    "max_ms": max(ms),
                    "grid_mib": boxes[0].nbytes / 2**20,
                    "escaped": int(sims[0].counts[COUNT_ESCAPED]),
                }
                del boxes
            del sims
        if "Boxes" in out:
            out["boxes_time_ratio"] = out["Boxes"]["median_ms"] / out["Shared"]["median_ms"]
        out["time_ratio"] = out["FractureFields"]["median_ms"] / out["Shared"]["median_ms"]
        out["memory_ratio"] = out["FractureFields"]["grid_mib"] / out["Shared"]["grid_mib"]
        ff = out["FractureFields"]
        out["memory_ratio_with_cache"] = (ff["grid_mib"] + ff["slot_cache_mib"]) / out["Shared"]["grid_mib"]
        rows.append(out)
        print(json.dumps(out), flush=True)
    dev = torch.cuda.get_device_name(a.device) if a.device.startswith("cuda") else "cpu"
    print(f"\n### K fragments ({dev}, {len(P)} particles, {a.n}³, {a.sort} order)\n")
    print(
        "| K | Shared ms | FractureFields ms | × Shared | Shared MiB | FF MiB | × memory | FF slot cache MiB "
        "| × memory with it | pool rows | overflow |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        s, f = r["Shared"], r["FractureFields"]
        print(
            f"| {r['K']} | {s['median_ms']:.4f} | {f['median_ms']:.4f} | {r['time_ratio']:.3f} | {s['grid_mib']:.1f} | "
            f"{f['grid_mib']:.1f} | {r['memory_ratio']:.3f} | {f['slot_cache_mib']:.1f} | "
            f"{r['memory_ratio_with_cache']:.3f} | {f['pool_rows']} | {f['slot_overflow']} |"
        )
    if any("Boxes" in r for r in rows):
        print("\n| K | per-fragment boxes ms | × Shared | box MiB | × Shared's grid | escaped stencils |")
        print("|---|---|---|---|---|---|")
        for r in rows:
            b = r["Boxes"]
            print(
                f"| {r['K']} | {b['median_ms']:.4f} | {r['boxes_time_ratio']:.3f} | {b['grid_mib']:.1f} | "
                f"{b['grid_mib'] / r['Shared']['grid_mib']:.3f} | {b['escaped']} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
