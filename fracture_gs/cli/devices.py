"""Device choice (`auto|cpu|cuda[:N]`) and Warp's set-up for the commands that simulate."""

from __future__ import annotations

import contextlib
import os
import re
import sys

from . import CliError, held_interrupts

DEVICE_RE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")


FORK_SAFE_CHECK = "PYTORCH_NVML_BASED_CUDA_CHECK"
"""torch's switch that makes `torch.cuda.is_available()` ask NVML instead of the CUDA driver (whose start-up in a
process leaves CUDA unusable in the children it forks later; `device_count` asks NVML already)."""


@contextlib.contextmanager
def fork_safe_cuda_checks(on: bool = True):
    """Inside, `_cuda_devices` (so `resolve_device`) leaves the CUDA driver unstarted (`FORK_SAFE_CHECK`): for a
    run that forks CUDA workers after its device checks (`render-sim --schedule processes` on a GPU)."""
    before = os.environ.get(FORK_SAFE_CHECK)
    if on:
        os.environ[FORK_SAFE_CHECK] = "1"
    try:
        yield
    finally:
        if on and before is None:
            os.environ.pop(FORK_SAFE_CHECK, None)
        elif on:
            os.environ[FORK_SAFE_CHECK] = before


def _cuda_devices() -> tuple[bool, int, str]:
    """(available, count, reason) from torch, imported lazily; never touches gsplat."""
    try:
        with held_interrupts():  # Ctrl-C inside torch's C++ start-up would abort the process: raise it after
            import torch
    except Exception as exc:  # noqa: BLE001 - report, do not crash
        return False, 0, f"torch cannot be imported ({exc})"
    if not torch.cuda.is_available():
        build = "CPU-only torch build" if torch.version.cuda is None else "no CUDA device or driver"
        return False, 0, f"torch.cuda.is_available() is False ({build})"
    return True, torch.cuda.device_count(), "torch.cuda.is_available() is True"


def resolve_device(spec: str) -> str:
    """Check `auto|cpu|cuda[:N]` and resolve `auto`; a CUDA device must exist."""
    spec = "auto" if spec is None else str(spec).strip().lower()
    if not DEVICE_RE.match(spec):
        raise CliError(f"--device {spec!r} is not a device; use auto, cpu, cuda or cuda:N (e.g. cuda:0).")
    if spec == "cpu":
        return "cpu"
    available, count, reason = _cuda_devices()
    if spec == "auto":
        return "cuda:0" if available else "cpu"
    if not available:
        raise CliError(
            f"--device {spec} was requested but CUDA is not available here ({reason}); use --device cpu or auto."
        )
    index = int(spec.split(":")[1]) if ":" in spec else 0
    if index >= count:
        raise CliError(
            f"--device {spec} does not exist; this machine has {count} CUDA device(s), cuda:0 to cuda:{count - 1}."
        )
    return f"cuda:{index}"


MODULE_LOAD_RE = re.compile(r"^\s*Module (\S+).*? load on device '[^']*'.*? took ([0-9.]+) ms\s*\((\w+)\)")
"""Warp's line for a kernel module load (`Module NAME HASH load on device 'cpu' took 1.20 ms  (cached)`)."""


class _QuietWarpLogger:
    """Warp's messages for the CLI: debug and info lines (module loads, the start-up banner) dropped,
    warnings and errors passed to the logger that was active before. A module load line of a profiled run
    becomes a "module loads" row of its profile (`profiling.STARTUP`), cached or compiled."""

    def __init__(self, inner) -> None:
        self.inner = inner

    def debug(self, message: str) -> None:
        pass

    def info(self, message: str) -> None:
        from ..profiling import phases

        if phases.enabled:
            match = MODULE_LOAD_RE.match(message)
            if match and match[3] in ("cached", "compiled"):
                phases.note_startup("module loads", float(match[2]) / 1000.0, compiled=match[3] == "compiled")

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        self.inner.warning(message, category=category, stacklevel=stacklevel + 1)

    def error(self, message: str) -> None:
        self.inner.error(message)


def _prepare_warp(init: bool = True) -> None:
    """The CLI is an application, so it gives Warp the application's logger (`wp.set_logger`, Warp's hook
    for host applications; `wp.config` is left alone): no per-module load lines, and on a machine without
    a CUDA driver Warp's native start-up warning is kept off stderr so user errors stay one line
    (`fracture-gs info` reports devices). The library itself never does this (`fracture_gs.runtime`).
    Without `init` only the logger: Warp starts at its first use, after a run has forked its CUDA workers
    (Warp's start-up starts the CUDA driver, which a forked child cannot use after its parent did)."""
    import warp as wp

    from ..runtime import ensure_warp

    if not isinstance(wp.get_logger(), _QuietWarpLogger):
        wp.set_logger(_QuietWarpLogger(wp.get_logger()))
    if not init:
        return
    available, _, _ = _cuda_devices()
    if available:
        ensure_warp()
        return
    sys.stderr.flush()
    saved, devnull = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        ensure_warp()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
