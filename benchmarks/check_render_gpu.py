#!/usr/bin/env python
"""Cross-check the torch rasterizer against gsplat's CUDA rasterizer: PSNR and time per frame.

On a GPU machine with gsplat (H100/H200):
    python benchmarks/check_render_gpu.py                  # exit 1 if any PSNR < 40 dB
On a CPU (smoke test; never imports gsplat): the torch backend (float32) is compared with the
float64 per-pixel reference (small scenes) or the torch backend in float64 (large ones):
    python benchmarks/check_render_gpu.py --cpu-dry-run

Scenes: three random Gaussian clouds (isotropic / needle-and-disc anisotropic under a random
deformation F / a large mixed cloud) and, when `fracture_gs.assets` can build them, bread and
ficus (size="small"). Every scene goes through the full per-frame path: Σ = F Σ⁰ Fᵀ, SH (degree 3
for the clouds) evaluated with the view direction rotated by R(F)ᵀ, then `render` in the classic
and antialiased modes, both backends on the same tensors. The Markdown table is printed last.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
import traceback
from dataclasses import dataclass

import torch

from fracture_gs.io.gaussian_set import quat_to_matrix
from fracture_gs.render import (
    deform_covariances,
    orbit,
    polar_rotation,
    render,
    render_reference,
    sh_colors,
    visible_mask,
)

PSNR_MIN = 40.0


@dataclass
class Scene:
    name: str
    means: torch.Tensor  # [N, 3]
    covars: torch.Tensor  # [N, 3, 3]
    sh: torch.Tensor  # [N, K, 3]
    opacities: torch.Tensor  # [N]
    R: torch.Tensor | None  # [N, 3, 3] polar rotation of F, or None
    width: int
    height: int


def _rotations(n: int, g: torch.Generator) -> torch.Tensor:  # [n, 3, 3]
    return quat_to_matrix(torch.randn(n, 4, generator=g))


def random_cloud(name: str, n: int, size: tuple[int, int], kind: str, seed: int) -> Scene:
    """Random Gaussians in a unit-ish blob. kind: iso | aniso (needles/discs, deformed by F) | mixed."""
    g = torch.Generator().manual_seed(seed)
    means = torch.randn(n, 3, generator=g) * torch.tensor([0.35, 0.3, 0.25])
    base = 0.6 * n ** (-1 / 3)  # keeps coverage comparable across n
    if kind == "iso":
        s = (base * torch.exp(0.3 * torch.randn(n, 1, generator=g))).expand(n, 3)
    elif kind == "aniso":
        ratio = torch.exp(torch.rand(n, 1, generator=g) * math.log(20.0))  # 1:1 … 20:1
        needle = torch.rand(n, 1, generator=g) < 0.5
        s = base * torch.where(
            needle,
            torch.cat([ratio, 1 / ratio.sqrt(), 1 / ratio.sqrt()], 1),
            torch.cat([ratio.sqrt(), ratio.sqrt(), 1 / ratio], 1),
        )
    else:  # mixed: mostly small, some large soft ones
        s = base * torch.exp(0.8 * torch.randn(n, 3, generator=g))
        big = torch.rand(n, generator=g) < 0.01
        s[big] *= 6
    M = _rotations(n, g) * s[:, None, :]
    cov0 = M @ M.transpose(1, 2)
    sh = 0.3 * torch.randn(n, 16, 3, generator=g)
    sh[:, 0] = (torch.rand(n, 3, generator=g) - 0.5) / 0.28209479177387814
    opac = 0.05 + 0.95 * torch.rand(n, generator=g)
    R = None
    if kind == "aniso":  # a smooth deformation: twist about z plus a stretch
        ang = 0.8 * means[:, 2:3]
        c, si = torch.cos(ang), torch.sin(ang)
        F = torch.zeros(n, 3, 3)
        F[:, 0, 0], F[:, 0, 1], F[:, 1, 0], F[:, 1, 1], F[:, 2, 2] = c[:, 0], -si[:, 0], si[:, 0], c[:, 0], 1.0
        F = F @ torch.diag(torch.tensor([1.3, 0.9, 1.0])) + 0.05 * torch.randn(n, 3, 3, generator=g)
        means = (F @ means[:, :, None])[..., 0]
        cov0 = deform_covariances(F, cov0)
        R = polar_rotation(F)
    return Scene(name, means, cov0, sh, opac, R, *size)


def asset_scene(name: str, size: tuple[int, int]) -> Scene:
    from fracture_gs import assets  # another engineer's module: may be missing or in flux

    gs = assets.build(name, size="small")
    keep = visible_mask(gs.interior, torch.zeros_like(gs.interior), False)
    gs = gs.subset(keep)
    return Scene(name, gs.means.float(), gs.covariances().float(), gs.sh.float(), gs.opacities.float(), None, *size)


def camera_for(scene: Scene, device):
    c = scene.means.median(dim=0).values
    r = float(torch.quantile((scene.means - c).norm(dim=1), 0.98)) if len(scene.means) else 1.0
    dist = 1.15 * r / math.sin(math.radians(20.0))
    return orbit(c.tolist(), dist, 20.0, -70.0, (0, 0, 1), 40.0, scene.width, scene.height).to(device)


def psnr(a: torch.Tensor, b: torch.Tensor) -> float:
    mse = float(((a.double() - b.double()) ** 2).mean())
    return math.inf if mse == 0 else -10 * math.log10(mse)


def timed(fn, device, repeats: int) -> tuple[object, float]:
    """(last output, median seconds per call) after one warm-up call."""
    out = fn()
    times = []
    for _ in range(repeats):
        if device.type == "cuda":
            start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
            start.record()
            out = fn()
            end.record()
            torch.cuda.synchronize()
            times.append(start.elapsed_time(end) / 1e3)
        else:
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def check_scene(scene: Scene, device, dry: bool, repeats: int) -> list[dict]:
    cam = camera_for(scene, device)
    means, covars, opac = scene.means.to(device), scene.covars.to(device), scene.opacities.to(device)
    R = scene.R.to(device) if scene.R is not None else None
    colors = sh_colors(scene.sh.to(device), means, cam.campos, R)
    rows = []
    for mode in ("classic", "antialiased"):
        torch_fn = lambda mode=mode: render(means, covars, colors, opac, cam, backend="torch", mode=mode)
        out_t, t_torch = timed(torch_fn, device, repeats)
        if dry:
            work = len(means) * scene.width * scene.height
            if work <= 3e7:
                ref_name, t_ref = "reference f64", math.nan
                out_r = render_reference(means, covars, colors, opac, cam, mode=mode)
            else:
                ref_name = "torch f64"
                out_r, t_ref = timed(
                    lambda mode=mode: render(
                        means.double(), covars.double(), colors.double(), opac.double(), cam, backend="torch", mode=mode
                    ),
                    device,
                    1,
                )
        else:
            ref_name = "gsplat"
            out_r, t_ref = timed(
                lambda mode=mode: render(means, covars, colors, opac, cam, backend="gsplat", mode=mode), device, repeats
            )
            assert out_r.backend == "gsplat"
        assert out_t.backend == "torch"
        p = psnr(out_t.image, out_r.image)
        rows.append(
            dict(
                scene=scene.name,
                n=len(means),
                size=f"{scene.width}x{scene.height}",
                mode=mode,
                ref=ref_name,
                psnr=p,
                dalpha=float((out_t.alpha.double() - out_r.alpha.double()).abs().max()),
                coverage=float(out_r.alpha.float().mean()),
                t_ref=t_ref,
                t_torch=t_torch,
            )
        )
        r = rows[-1]
        print(
            f"  {mode:11s} PSNR torch vs {ref_name}: {p:6.2f} dB  max|Δalpha| {r['dalpha']:.1e}  "
            f"coverage {r['coverage']:.2f}  {ref_name} {1e3 * t_ref:8.1f} ms  torch {1e3 * t_torch:8.1f} ms",
            flush=True,
        )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cpu-dry-run", action="store_true", help="run on the CPU without gsplat (smoke test)")
    ap.add_argument("--repeats", type=int, default=None, help="timed repeats per render (default 10 GPU, 2 CPU)")
    ap.add_argument("--no-assets", action="store_true", help="skip the bread/ficus asset scenes")
    args = ap.parse_args(argv)

    dry = args.cpu_dry_run
    if not dry and not torch.cuda.is_available():
        print("check_render_gpu: no CUDA device visible; run on a GPU machine or pass --cpu-dry-run")
        return 2
    device = torch.device("cpu" if dry else "cuda")
    repeats = args.repeats or (2 if dry else 10)
    print(
        f"torch {torch.__version__}, device {device}" + ("" if dry else f" ({torch.cuda.get_device_name()})"),
        flush=True,
    )
    if not dry:
        import gsplat

        print(f"gsplat {gsplat.__version__}", flush=True)

    if dry:
        clouds = [
            ("cloud_iso", 1_500, (96, 80), "iso"),
            ("cloud_aniso", 6_000, (160, 128), "aniso"),
            ("cloud_mixed", 20_000, (256, 256), "mixed"),
        ]
        asset_size = (256, 256)
    else:
        clouds = [
            ("cloud_iso", 10_000, (256, 256), "iso"),
            ("cloud_aniso", 200_000, (800, 600), "aniso"),
            ("cloud_mixed", 1_000_000, (1280, 720), "mixed"),
        ]
        asset_size = (512, 512)
    builders = [
        (name, lambda a=(name, n, size, kind, 7 + k): random_cloud(*a))
        for k, (name, n, size, kind) in enumerate(clouds)
    ]
    if not args.no_assets:
        builders += [(name, lambda nm=name: asset_scene(nm, asset_size)) for name in ("bread", "ficus")]

    rows, failures, skipped = [], [], []
    for name, build in builders:
        try:
            scene = build()
        except Exception as e:  # assets are optional here
            if name in ("bread", "ficus"):
                skipped.append(f"{name}: {type(e).__name__}: {e}")
                print(f"[{name}] skipped: could not build the asset ({type(e).__name__}: {e})", flush=True)
                continue
            raise
        print(f"[{name}] N={len(scene.means)} {scene.width}x{scene.height}", flush=True)
        try:
            rows += check_scene(scene, device, dry, repeats)
        except Exception:
            traceback.print_exc()
            failures.append(f"{name}: exception")
        if device.type == "cuda":
            torch.cuda.empty_cache()

    failures += [
        f"{r['scene']}/{r['mode']}: PSNR {r['psnr']:.2f} dB < {PSNR_MIN}" for r in rows if r["psnr"] < PSNR_MIN
    ]
    print()
    print("| scene | N | size | mode | vs | PSNR [dB] | max abs Δalpha | vs [ms/frame] | torch [ms/frame] |")
    print("|---|---:|---|---|---|---:|---:|---:|---:|")
    for r in rows:
        ps = "inf" if math.isinf(r["psnr"]) else f"{r['psnr']:.2f}"
        tr = "—" if math.isnan(r["t_ref"]) else f"{1e3 * r['t_ref']:.1f}"
        print(
            f"| {r['scene']} | {r['n']} | {r['size']} | {r['mode']} | {r['ref']} | {ps} | {r['dalpha']:.1e} | "
            f"{tr} | {1e3 * r['t_torch']:.1f} |"
        )
    for s in skipped:
        print(f"\nskipped {s}")
    if failures:
        print("\nFAIL: " + "; ".join(failures))
        return 1
    print(f"\nOK: every PSNR ≥ {PSNR_MIN} dB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
