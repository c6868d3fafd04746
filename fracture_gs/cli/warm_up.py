"""`fracture-gs info --warm-up`: everything a run compiles on first use, compiled once, ahead of use.

On a fresh machine the first run compiles: Warp each kernel module it launches (seconds to a minute each on a CPU),
gsplat its CUDA code (about a minute). A machine set up ahead of use does it here instead, step by step, each
step printed with its time and whether it came from the cache:

1. Warp initialised (`devices._prepare_warp`, as a run does).
2. Every Warp kernel module of `fracture_gs.sim` (the simulator, its diagnostics, the differentiable solver) and
   of `fracture_gs.linalg`, found by importing those modules and collecting the modules of the kernels they hold
   (the fast-math grid updates each build in a module of their own), loaded on the device (`wp.load_module`):
   from the kernel cache, or compiled into it.
3. One frame of a tiny built-in scene on the device: its launches load what they need, so a load here is a
   module step 2 missed (the summary names how many).
4. On CUDA, gsplat's CUDA code (`render.warm_up.compile_gsplat`, the build a run starts in the background);
   on the CPU nothing: the Warp rasterizer (`render.raster_kernels`, a step-2 module there) draws, gsplat is never
   built.
5. Python's bytecode of the packages a run imports, where it is missing (`bytecode.compile_stale`): with
   PYTHONDONTWRITEBYTECODE set and wheels installed without it, every start compiled torch's sources again.

Cache hits are read from Warp's own load lines ("(cached)", "(compiled)") through a logger set for the duration
(`wp.set_logger`, the hook the CLI's quiet logger uses); a module this process had loaded already says so.
"""

from __future__ import annotations

import importlib
import pkgutil
import time
from dataclasses import dataclass
from typing import Callable

from .devices import MODULE_LOAD_RE

KERNEL_PACKAGES = ("fracture_gs.linalg", "fracture_gs.sim")
"""Where the package's Warp kernels live (modules, or packages walked for their modules)."""
CPU_KERNEL_PACKAGES = ("fracture_gs.render.raster_kernels",)
"""Kernels only a CPU run launches (the Warp rasterizer; gsplat draws on CUDA)."""
TINY_SCENE = "bread"
TINY_PARTICLES = 300  # particles of the tiny scene's one frame


@dataclass
class Step:
    """One step of the warm-up: what, how long [s], and how (cached, compiled, already loaded, or a phrase)."""

    name: str
    seconds: float
    status: str


class _LoadLines:
    """A Warp logger that keeps the module load lines (name, status) and passes everything on to `inner`."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.loads: list[tuple[str, str]] = []

    def debug(self, message: str) -> None:
        self.inner.debug(message)

    def info(self, message: str) -> None:
        match = MODULE_LOAD_RE.match(message)
        if match:
            self.loads.append((match[1], match[3]))
        self.inner.info(message)

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        self.inner.warning(message, category=category, stacklevel=stacklevel + 1)

    def error(self, message: str) -> None:
        self.inner.error(message)


def kernel_modules(device: str = "cpu") -> list:
    """The Warp modules (`warp.Module`) of the package's kernels that `device` launches, by name: every module of
    `KERNEL_PACKAGES` (and on the CPU of `CPU_KERNEL_PACKAGES`) imported, and the module of each kernel found in it
    (directly, or in a dict, list or tuple it holds)."""
    import warp as wp

    names = []
    for name in KERNEL_PACKAGES + (CPU_KERNEL_PACKAGES if device == "cpu" else ()):
        module = importlib.import_module(name)
        names.append(name)
        if hasattr(module, "__path__"):
            names += [m.name for m in pkgutil.walk_packages(module.__path__, f"{name}.")]
    found: dict[int, object] = {}
    for name in names:
        for value in list(vars(importlib.import_module(name)).values()):
            held = value.values() if isinstance(value, dict) else value if isinstance(value, (list, tuple)) else ()
            for kernel in [value, *held]:
                if isinstance(kernel, wp.Kernel):
                    found.setdefault(id(kernel.module), kernel.module)
    return sorted(found.values(), key=lambda m: m.name)


def _status(loads: list[tuple[str, str]]) -> str:
    """How the loads one call made came about: "cached", "compiled", both counted, or "already loaded"."""
    if not loads:
        return "already loaded"
    kinds = [status for _, status in loads]
    if len(set(kinds)) == 1:
        return kinds[0]
    return ", ".join(f"{kinds.count(k)} {k}" for k in sorted(set(kinds)))


def load_modules(modules: list, device: str, log: _LoadLines, report: Callable[[Step], None]) -> list[Step]:
    """Load each Warp module on `device`; one Step each, reported as it ends."""
    import warp as wp

    steps = []
    for module in modules:
        start, before = time.perf_counter(), len(log.loads)
        wp.load_module(module, device=device)
        steps.append(Step(f"module {module.name}", time.perf_counter() - start, _status(log.loads[before:])))
        report(steps[-1])
    return steps


def tiny_frame(device: str) -> None:
    """One frame of `TINY_SCENE` at `TINY_PARTICLES` particles (variant full) on `device`."""
    import torch

    from ..io.config import apply_overrides, find_config, load_config
    from ..pipeline import make_simulator, prepare_scene, simulate

    cfg = load_config(find_config(TINY_SCENE))
    cfg = apply_overrides(cfg, frames=1, variants="full", keys={"particles": TINY_PARTICLES})
    scene = prepare_scene(cfg, device)
    gs = scene.gaussians
    sim = make_simulator(scene.cfg, gs, "full", device)
    cov0 = gs.covariances().to(device, torch.float32)  # [N, 3, 3]
    for _ in simulate(sim, cov0, 1, cfg.frame_dt, carrier=gs.carrier):
        pass


def gsplat_step(device: str, say: Callable[[str], None]) -> Step:
    """gsplat's CUDA code built (or found) and run once on `device`."""
    import importlib.util

    from ..errors import RenderError
    from ..render.warm_up import compile_gsplat, gsplat_needs_compile
    from .hardware import version

    if version("gsplat") == "not installed":
        raise RenderError("gsplat is not installed; install it (pip install gsplat) or render with backend 'torch'")
    needs = gsplat_needs_compile()
    if needs:
        say("  (gsplat builds its CUDA code now: about a minute, once)")
    start = time.perf_counter()
    compile_gsplat(device, spinner=False)
    status = "compiled" if needs else "prebuilt" if importlib.util.find_spec("gsplat.csrc") else "cached"
    return Step("gsplat CUDA code", time.perf_counter() - start, status)


def warm_up(device: str, report: Callable[[Step], None], say: Callable[[str], None] = print) -> list[Step]:
    """Every step on `device` ("cpu" or "cuda:N"), each passed to `report` as it ends; returns them all."""
    import warp as wp

    from ..runtime import _initialised
    from .devices import _prepare_warp

    start, was = time.perf_counter(), _initialised()
    _prepare_warp()
    steps = [Step("Warp init (torch and Warp imported)", time.perf_counter() - start, "already" if was else "done")]
    report(steps[-1])
    log = _LoadLines(wp.get_logger())
    wp.set_logger(log)
    try:
        steps += load_modules(kernel_modules(device), device, log, report)
        start, before = time.perf_counter(), len(log.loads)
        tiny_frame(device)
        extra = log.loads[before:]
        named = f": {', '.join(name for name, _ in extra)}" if extra else ""
        steps.append(
            Step(
                f"one frame of {TINY_SCENE} ({TINY_PARTICLES} particles)",
                time.perf_counter() - start,
                f"{len(extra)} more module(s) loaded{named}",
            )
        )
        report(steps[-1])
    finally:
        wp.set_logger(log.inner)
    if device.startswith("cuda"):
        steps.append(gsplat_step(device, say))
    else:
        steps.append(Step("gsplat CUDA code", 0.0, "not needed on the CPU (the Warp rasterizer draws there)"))
    report(steps[-1])
    steps.append(bytecode_step())
    report(steps[-1])
    return steps


def bytecode_step() -> Step:
    """The missing bytecode of the packages a run imports (and of what this process imported) written once."""
    from .. import bytecode

    start = time.perf_counter()
    packages = bytecode.survey(bytecode.imported_packages())
    read_only = sorted(p.name for p in packages if p.stale and not p.writable)
    written, left = bytecode.compile_stale(packages)
    parts = [f"{written} module(s) compiled" if written else "cached"]
    if left:
        parts.append(f"{left} left as source (this Python cannot compile them, e.g. another version's syntax)")
    if read_only:
        parts.append(f"read-only, not written: {', '.join(read_only)} (set PYTHONPYCACHEPREFIX to a writable folder)")
    return Step("Python bytecode of the packages a run imports", time.perf_counter() - start, "; ".join(parts))


def _print_step(step: Step) -> None:
    print(f"  {step.name:<52}{step.seconds:8.2f} s  {step.status}", flush=True)


def cmd_warm_up(device: str) -> int:
    """`info --warm-up` on `device`: the steps, then one summary line."""
    print(f"\nwarm-up on {device}:", flush=True)
    start = time.perf_counter()
    steps = warm_up(device, _print_step)
    modules = [s for s in steps if s.name.startswith("module ")]
    counts = {k: sum(k in s.status for s in modules) for k in ("cached", "compiled", "already loaded")}
    print(
        f"warm-up done in {time.perf_counter() - start:.1f} s: {len(modules)} Warp kernel modules ("
        + ", ".join(f"{n} {k}" for k, n in counts.items())
        + "); later runs on this machine load them from the cache"
    )
    return 0
