"""The fragment-aware surface measure (`penetration.surface_depth`) in Warp against its torch twin, on three jittered
blocks pressed into each other by two spacings (the shape of a shared-field run whose pieces stay together).

    python benchmarks/surface_measure.py --device cuda:0 --cells 48     # 331,776 particles
    python benchmarks/surface_measure.py --device cpu --cells 20
"""

from __future__ import annotations

import argparse
import time

import torch

from fracture_gs.sim.diagnostics import penetration as pen


def pressed_blocks(n: int, spacing: float, device: str) -> tuple[torch.Tensor, torch.Tensor]:  # [3n³, 3], [3n³]
    g = torch.Generator().manual_seed(0)
    parts, ids = [], []
    for k, x0 in enumerate((0.0, (n - 2) * spacing, -(n - 2) * spacing)):
        axes = [torch.arange(n) * spacing + x0, torch.arange(n) * spacing, torch.arange(n) * spacing]
        p = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).double()
        parts.append(p + 0.2 * spacing * (torch.rand(p.shape, generator=g, dtype=torch.float64) - 0.5))
        ids.append(torch.full((len(p),), k))
    return torch.cat(parts).to(device), torch.cat(ids).to(device)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--cells", type=int, default=20, help="particles along each block's edge")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    spacing = 0.005
    x, frag = pressed_blocks(a.cells, spacing, a.device)
    cal = pen.calibrate(x[frag == 0], frag[frag == 0])  # one block alone: the scales at a latch
    cal["filled"] = cal["filled"].repeat(3)

    def sync():
        if a.device.startswith("cuda"):
            torch.cuda.synchronize()

    for twin in (False, True):
        pen.surface_depth(x, frag, cal, twin=twin)
        sync()
        t = time.perf_counter()
        for _ in range(a.repeats):
            depth, into = pen.surface_depth(x, frag, cal, twin=twin)
        sync()
        ms = (time.perf_counter() - t) / a.repeats * 1e3
        name = "torch twin" if twin else "Warp"
        print(f"{name}: {ms:.1f} ms a call, {len(x)} particles, {int((into >= 0).sum())} behind another piece, "
              f"deepest {float(depth.max()) / spacing:.3f} spacings")  # fmt: skip


if __name__ == "__main__":
    main()
