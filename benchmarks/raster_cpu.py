#!/usr/bin/env python
"""Time per frame of the CPU rasterizers: the torch tile rasterizer and the Warp kernel (`render.raster_kernels`).

    python benchmarks/raster_cpu.py                      # bread (20k particles) at 320x240, 15 frames each
    python benchmarks/raster_cpu.py --repeats 31 --threads 1

The scene is the README main job's (bread, preset small, frame 0's camera, SH colours from it), drawn two ways:
"drawn", the Gaussians a render-sim frame draws before a fracture (the surface; interior hidden), and "all",
every particle's Gaussian (the 20k upper bound, as once fractures expose the interior). Both backends render
the same tensors, interleaved frame by frame so that a shared machine's load shifts both alike; each row gives
the median and minimum wall time per frame and the median process CPU time per frame (all threads: torch's
intra-op threads count). The Warp row is split into its parts (torch projection, depth sort and Warp tile lists, the
compositing kernel)
and the largest per-channel difference between the two images is printed (the backends share the math).
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import torch

from fracture_gs.io.config import apply_overrides, find_config, load_config
from fracture_gs.pipeline import prepare_scene
from fracture_gs.render import sh_colors, splat
from fracture_gs.render.camera import frame_camera
from fracture_gs.render.raster_kernels import composite, tile_lists


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed(fn) -> tuple[float, float]:
    """(wall, CPU) seconds of one call."""
    w, c = time.perf_counter(), cpu_seconds()
    fn()
    return time.perf_counter() - w, cpu_seconds() - c


def scene_sets(particles: int, width: int, height: int) -> dict:
    cfg = load_config(find_config("bread"))
    cfg = apply_overrides(cfg, resolution=f"{width}x{height}", keys={"particles": particles})
    scene = prepare_scene(cfg, "cpu")
    gs = scene.gaussians
    cam = frame_camera(scene.cfg, 0)
    out = {}
    for name, keep in (("drawn", ~gs.interior), ("all", torch.ones_like(gs.interior))):
        means = gs.means.float()[keep]  # [M, 3]
        cols = sh_colors(gs.sh.float()[keep], means, cam.campos)
        out[name] = (means, gs.covariances().float()[keep], cols, gs.opacities.float()[keep], cam)
    return out, tuple(scene.cfg.render.background)


def bench(args, means, covars, colors, opac, cam, bg) -> tuple[list, float]:
    W, H = cam.width, cam.height
    frames = {b: (lambda b=b: splat.render(means, covars, colors, opac, cam, bg, backend=b)) for b in ("torch", "warp")}
    bgt = torch.tensor(bg)
    state = {}

    def project():
        view, K = cam.viewmat, cam.K
        state["proj"] = splat.project_gaussians(means, covars, view, K, W, H, 0.3, 0.01, 1e10, "classic", opac)

    def lists():
        p = state["proj"]
        state["lists"] = tile_lists(splat._depth_order(p), p.means2d, p.radii, W, H, splat.TILE_CPU)

    def kernel():
        p = state["proj"]
        composite(*state["lists"], p.means2d, p.conics, p.opacities, colors, bgt, W, H, splat.TILE_CPU)

    parts = {"torch": frames["torch"], "warp": frames["warp"], "  projection": project}
    parts.update({"  depth order + tile lists": lists, "  compositing kernel": kernel})
    for _ in range(2):  # warm-up: Warp's module load, torch's allocator
        for fn in parts.values():
            fn()
    samples: dict[str, list] = {k: [] for k in parts}
    for _ in range(args.repeats):
        for name, fn in parts.items():
            samples[name].append(timed(fn))
    diff = (frames["torch"]().image - frames["warp"]().image).abs().max().item()
    rows = []
    for name, s in samples.items():
        wall, cpu = [w for w, _ in s], [c for _, c in s]
        rows.append((name, 1e3 * statistics.median(wall), 1e3 * min(wall), 1e3 * statistics.median(cpu)))
    return rows, diff


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=15, help="timed frames per backend (default 15)")
    p.add_argument("--particles", type=int, default=20000, help="bread particles (default 20000, the main job's)")
    p.add_argument("--resolution", default="320x240", help="WxH (default 320x240, the main job's)")
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    args = p.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    from fracture_gs.cli.devices import _prepare_warp

    _prepare_warp()  # as the CLI: Warp's start-up and module-load lines kept quiet
    width, height = (int(v) for v in args.resolution.lower().split("x"))
    sets, bg = scene_sets(args.particles, width, height)
    print(f"bread, {args.particles} particles, {width}x{height}, torch threads {torch.get_num_threads()}, ", end="")
    print(f"{args.repeats} frames per row, load average {' '.join(f'{v:.2f}' for v in __import__('os').getloadavg())}")
    print("\n| set | Gaussians | backend | median wall ms | min wall ms | median CPU ms |")
    print("|---|---|---|---|---|---|")
    diffs = {}
    for name, (means, covars, colors, opac, cam) in sets.items():
        rows, diffs[name] = bench(args, means, covars, colors, opac, cam, bg)
        for backend, med, lo, cpu in rows:
            print(f"| {name} | {len(means)} | {backend} | {med:.1f} | {lo:.1f} | {cpu:.1f} |")
    for name, d in diffs.items():
        print(f"\n{name}: largest |torch − warp| over pixels and channels: {d:.2e} (1/255 = {1 / 255:.2e})")


if __name__ == "__main__":
    main()
