"""What `fracture-gs info` reports, found without importing torch, Warp or gsplat (seconds each to import).

Versions come from the installed packages' metadata; torch's CUDA build from its generated `torch/version.py`
(read as text); the CUDA devices from the driver itself (`libcuda`, through ctypes: the calls torch's own
check ends in); Warp's kernel cache folder the way `warp.init()` picks it. A run still decides with torch
(`devices._cuda_devices`); this module says what that check will find: no CUDA build of torch, no driver or
no device, or a driver older than torch's CUDA all mean the CPU.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import sys
from importlib import metadata
from typing import Optional

CC_MAJOR, CC_MINOR = 75, 76  # CU_DEVICE_ATTRIBUTE_COMPUTE_CAPABILITY_MAJOR / _MINOR


def version(dist: str) -> str:
    """The installed version of distribution `dist` (e.g. "warp-lang"), or "not installed"."""
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def _package_dir(module: str) -> Optional[str]:
    """The folder of top-level package `module`, found without importing it (None: not installed, or a single
    module rather than a package): `bytecode.package_root`, which finds it for the bytecode row too."""
    from ..bytecode import package_root

    root = package_root(module)
    return str(root) if root is not None and root.is_dir() else None


def torch_cuda_build() -> tuple[bool, Optional[str]]:
    """(torch installed, the CUDA version torch was built for or None for a CPU-only or ROCm build), from
    `torch/version.py`, which torch's build writes as plain assignments (`cuda: Optional[str] = '12.8'`)."""
    folder = _package_dir("torch")
    if folder is None:
        return False, None
    try:
        tree = ast.parse(open(os.path.join(folder, "version.py"), encoding="utf-8").read())
    except (OSError, SyntaxError, ValueError):
        return True, None
    for node in tree.body:
        target = (
            node.target
            if isinstance(node, ast.AnnAssign)
            else (node.targets[0] if isinstance(node, ast.Assign) else None)
        )
        if isinstance(target, ast.Name) and target.id == "cuda" and node.value is not None:
            try:
                value = ast.literal_eval(node.value)
            except ValueError:
                return True, None
            return True, str(value) if value else None
    return True, None


def driver_devices() -> tuple[Optional[int], list[tuple[str, float, str]], str]:
    """(the driver's CUDA version as 12080 for 12.8 or None, [(name, GiB, "sm_XY")] per visible device, why
    not when the list is empty), from the CUDA driver library; CUDA_VISIBLE_DEVICES applies as for torch."""
    import ctypes

    name = {"win32": "nvcuda.dll", "darwin": ""}.get(sys.platform, "libcuda.so.1")
    try:
        cuda = ctypes.CDLL(name) if name else None
    except OSError:
        cuda = None
    if cuda is None:
        return None, [], "no CUDA driver (libcuda not found)"
    count, driver = ctypes.c_int(0), ctypes.c_int(0)
    if cuda.cuInit(0) != 0:
        return None, [], "the CUDA driver found no usable device (cuInit failed)"
    cuda.cuDriverGetVersion(ctypes.byref(driver))
    if cuda.cuDeviceGetCount(ctypes.byref(count)) != 0 or count.value == 0:
        return driver.value, [], "the CUDA driver reports no device"
    found = []
    for i in range(count.value):
        dev, text, total = ctypes.c_int(0), ctypes.create_string_buffer(256), ctypes.c_size_t(0)
        major, minor = ctypes.c_int(0), ctypes.c_int(0)
        cuda.cuDeviceGet(ctypes.byref(dev), i)
        cuda.cuDeviceGetName(text, len(text), dev)
        cuda.cuDeviceTotalMem_v2(ctypes.byref(total), dev)
        cuda.cuDeviceGetAttribute(ctypes.byref(major), CC_MAJOR, dev)
        cuda.cuDeviceGetAttribute(ctypes.byref(minor), CC_MINOR, dev)
        found.append((text.value.decode(errors="replace"), total.value / 2**30, f"sm_{major.value}{minor.value}"))
    return driver.value, found, ""


def cuda_status() -> tuple[bool, str, list[tuple[str, float, str]]]:
    """(torch will see CUDA, the reason in words, the devices) without importing torch: torch needs a CUDA
    build, a driver with a device, and a driver of at least its CUDA major version (minor versions are
    compatible within a major version)."""
    installed, built = torch_cuda_build()
    if not installed:
        return False, "torch is not installed", []
    if built is None:
        return False, "CPU-only torch build", []
    try:
        driver, found, why = driver_devices()
    except (AttributeError, OSError, ValueError):  # a driver library that cannot be queried: ask torch, as a run does
        return _from_torch()
    if not found:
        return False, f"{why}; torch built for CUDA {built}", []
    have = f"{driver // 1000}.{driver % 1000 // 10}" if driver else "unknown"
    if driver and driver // 1000 < int(built.split(".")[0]):
        return False, f"the driver supports CUDA {have}, older than torch's CUDA {built}; update the driver", found
    return True, f"{len(found)} device(s), CUDA {built} (driver {have})", found


def _from_torch() -> tuple[bool, str, list[tuple[str, float, str]]]:
    """`cuda_status` the slow way, through torch (imported here), for a driver the probe cannot read."""
    from .devices import _cuda_devices

    available, count, reason = _cuda_devices()
    found = []
    if available:
        import torch

        for i in range(count):
            props = torch.cuda.get_device_properties(i)
            found.append((props.name, props.total_memory / 2**30, f"sm_{props.major}{props.minor}"))
    return available, reason, found


def warp_cache_dir() -> str:
    """Warp's kernel cache folder as `warp.init()` will choose it: WARP_CACHE_PATH/<version>, else the user cache
    folder of Warp's bundled appdirs (loaded on its own: importing `warp` would load its native library)."""
    warp_version = version("warp-lang")
    if os.environ.get("WARP_CACHE_PATH"):
        return os.path.join(os.path.realpath(os.environ["WARP_CACHE_PATH"]), warp_version) + "  (WARP_CACHE_PATH)"
    folder = _package_dir("warp")
    try:
        spec = importlib.util.spec_from_file_location(
            "_fracture_gs_warp_appdirs", os.path.join(folder or "", "_src", "thirdparty", "appdirs.py")
        )
        appdirs = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(appdirs)
        return appdirs.user_cache_dir(appname="warp", appauthor="NVIDIA", version=warp_version)
    except Exception:  # noqa: BLE001 - a private layout: say where to look instead of failing
        return "(default location; set WARP_CACHE_PATH to choose one)"
