"""How much grid K fragments need if each had its own dense box: the geometry behind the storage plan of
docs/DESIGN.md ("Grid storage: per-fragment boxes").

For the ficus shattered into K Voronoi pieces (as `benchmarks/bench_fragments.py` does), per K:
- the nodes of every fragment's own box (the bounding box of its particles' 3×3×3 stencils), summed,
  against the one box of the shared field and the whole grid;
- the nodes some particle's stencil reaches, per fragment, summed (the fields that hold mass);
- the nodes reached by two fragments or more (where fields meet: where contact is projected).

    python benchmarks/fragment_boxes.py                          # 171,553 particles, 128³, K = 2, 4, 8, 16
    python benchmarks/fragment_boxes.py --particles 3000 --n 32  # a smoke run

Geometry only: no simulation, CPU, a few seconds.
"""

from __future__ import annotations

import argparse
import json
import sys

import torch

from fracture_gs.paper.fragments import shattered_state, voronoi_topology

STENCIL = torch.stack(torch.meshgrid(*[torch.arange(3)] * 3, indexing="ij"), -1).reshape(27, 3)  # [27, 3]


def stencil_bases(x: torch.Tensor, dx: float) -> torch.Tensor:  # [N, 3] -> [N, 3]
    """The lowest node of each particle's quadratic B-spline stencil, floor(x/Δx − ½)."""
    return torch.floor(x.double() / dx - 0.5).long()


def box_nodes(base: torch.Tensor) -> int:
    """Nodes of the bounding box of the stencils whose lowest nodes are `base` [M, 3]."""
    if base.numel() == 0:
        return 0
    return int(torch.prod(base.max(0).values + 2 - base.min(0).values + 1))


def reached(base: torch.Tensor, n: int) -> torch.Tensor:  # [M, 3] -> [R] flat node keys, unique
    """The nodes the stencils reach, as flat keys of an (n + 3)³ grid (bases may sit one node outside)."""
    nodes = (base[:, None, :] + 1 + STENCIL[None]).reshape(-1, 3)
    m = n + 3
    return torch.unique((nodes[:, 0] * m + nodes[:, 1]) * m + nodes[:, 2])


def geometry(x: torch.Tensor, fragment: torch.Tensor, dx: float, n: int) -> dict:
    """The box and node counts for one labelling (`fragment` [N], ids 0 … K−1)."""
    base = stencil_bases(x, dx)
    per_box, per_reached, keys = 0, 0, []
    for k in torch.unique(fragment).tolist():
        b = base[fragment == k]
        per_box += box_nodes(b)
        r = reached(b, n)
        per_reached += r.numel()
        keys.append(r)
    _, counts = torch.unique(torch.cat(keys), return_counts=True)
    return {
        "fragments": int(torch.unique(fragment).numel()),
        "shared_box_nodes": box_nodes(base),
        "shared_reached_nodes": int(reached(base, n).numel()),
        "fragment_box_nodes": per_box,
        "fragment_reached_nodes": per_reached,
        "nodes_of_two_or_more": int((counts >= 2).sum()),
        "grid_nodes": n**3,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--particles", type=int, default=None, help="default: the paper's 171,553")
    p.add_argument("--n", type=int, default=128, help="grid cells per axis")
    p.add_argument("--K", default="2,4,8,16", help="Voronoi piece counts, comma-separated")
    p.add_argument("--json", action="store_true", help="print the rows as JSON instead of a table")
    args = p.parse_args(argv)
    cfg, P = shattered_state(args.particles, "cpu", args.n)  # the state and pieces of bench_fragments
    x, dx = P.x, cfg.sim.dx
    rows = []
    for K in (int(k) for k in args.K.split(",")):
        rows.append({"K": K, **geometry(x, voronoi_topology(P, K, dx).fragment, dx, args.n)})
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"ficus, {len(x):,} particles, {args.n}³ grid ({args.n**3:,} nodes)\n")
    print(
        "| K | fragment boxes (nodes) | × the shared box | nodes reached, Σ over fragments | × shared | nodes of ≥ 2 |"
    )
    print("|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['K']} | {r['fragment_box_nodes']:,} | {r['fragment_box_nodes'] / r['shared_box_nodes']:.2f} "
            f"| {r['fragment_reached_nodes']:,} | {r['fragment_reached_nodes'] / r['shared_reached_nodes']:.2f} "
            f"| {r['nodes_of_two_or_more']:,} |"
        )
    print(
        f"\nshared field: one box of {rows[0]['shared_box_nodes']:,} nodes, {rows[0]['shared_reached_nodes']:,} reached"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
