"""Python's cached bytecode of the packages a run imports: found missing by `info`, written once by `info --warm-up`.

Python compiles a module's source to bytecode when it imports it and keeps the result in `__pycache__` beside the
source, unless PYTHONDONTWRITEBYTECODE is set or the folder is read-only. Containers often set that variable and
install wheels without bytecode (`pip install --no-compile`, or wheels unpacked by hand); then every process
compiles torch's modules again. On the lent H200 hosts (2026-11-29) torch, numpy and setuptools shipped no
bytecode with PYTHONDONTWRITEBYTECODE=1, and `import torch` took 3.8–5.4 s against 2.2–2.6 s with bytecode;
a profile of the warm GPU job found 8 s of its process compiling sources (torch, Warp, the package itself, scipy).

`info` reports the packages whose bytecode is missing and will stay missing, `render-sim --profile` how many of the
modules it imported it compiled from source (`profile_note`); `info --warm-up` writes it, as pip does at install
time: `compileall` in a child process, given the stale files only. Freshness is read the way
Python reads it: the bytecode file at `importlib.util.cache_from_source` (which follows PYTHONPYCACHEPREFIX), this
interpreter's magic number, and the source's modification time and size in the header (or a hash-based file,
which Python checks against the source itself). Nothing here imports the packages it looks at.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Optional

RUN_PACKAGES = (
    "fracture_gs",
    "torch",
    "torchgen",
    "numpy",
    "warp",
    "scipy",
    "gsplat",
    "jaxtyping",
    "rich",
    "plyfile",
    "gsply",
    "cv2",
    "imageio_ffmpeg",
    "tqdm",
    "typing_extensions",
)
"""Top-level packages a render-sim run imports (a GPU run with gsplat and a fracture event; a captured scene's
reader). A test holds it to what a run really imports."""

SKIP_DIRS = frozenset({"__pycache__", "include", "csrc", "lib", "bin", "share", "node_modules"})
"""Folders of a package tree that hold no modules a run imports (C++ headers, CUDA sources, shared libraries)."""

_HASH_BASED = 0b1  # the header's flags bit of a hash-based .pyc (PEP 552)


@dataclass
class PackageBytecode:
    """One top-level package's sources and which of them lack fresh bytecode."""

    name: str
    root: Path  # the package's folder, or its one module file
    sources: list[Path] = field(default_factory=list)
    stale: list[Path] = field(default_factory=list)
    writable: bool = True  # every folder of a stale source can take a __pycache__

    @property
    def entry(self) -> Path:
        """The file every import of the package runs: its `__init__.py`, or the module file itself."""
        return self.root if self.root.is_file() else self.root / "__init__.py"

    @property
    def compiled_at_start(self) -> bool:
        """Whether each process compiles this package's sources: its entry has no fresh bytecode. (A few stale
        files in an otherwise compiled package are sources this Python cannot compile, e.g. another version's
        syntax, which pip's install step leaves as they are; no run imports them.)"""
        return self.entry in self.stale


def imported_packages() -> tuple[str, ...]:
    """`RUN_PACKAGES`, then every other top-level package this process has imported, outside the standard
    library (after a warm-up: what gsplat's loading pulls in, such as setuptools)."""
    extra = {m.split(".")[0] for m in list(sys.modules)} - set(sys.stdlib_module_names) - set(RUN_PACKAGES)
    return RUN_PACKAGES + tuple(sorted(m for m in extra if not m.startswith("_")))


def package_root(name: str) -> Optional[Path]:
    """The folder of top-level package `name` (or the file of a single-module distribution), found without
    importing it; None when it is not installed or is built in."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    locations = list(spec.submodule_search_locations or [])
    if locations:
        return Path(locations[0])
    if spec.origin and spec.origin.endswith(".py"):
        return Path(spec.origin)
    return None


def sources(root: Path) -> list[Path]:
    """The .py files under `root` (sorted), leaving out `SKIP_DIRS` and hidden folders; `root` itself if a file."""
    if root.is_file():
        return [root]
    found = []
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS and not d.startswith("."))
        found += [Path(folder, f) for f in sorted(files) if f.endswith(".py")]
    return found


def is_fresh(source: Path) -> bool:
    """Whether Python would load `source`'s cached bytecode rather than compile it: the file exists where this
    interpreter looks, carries its magic number, and (timestamp-based) records the source's mtime and size."""
    try:
        with open(importlib.util.cache_from_source(str(source)), "rb") as f:
            head = f.read(16)
        st = source.stat()
    except (OSError, NotImplementedError, ValueError):
        return False
    if len(head) < 16 or head[:4] != importlib.util.MAGIC_NUMBER:
        return False
    if int.from_bytes(head[4:8], "little") & _HASH_BASED:
        return True  # Python checks the source's hash itself (or was told not to)
    mtime, size = int.from_bytes(head[8:12], "little"), int.from_bytes(head[12:16], "little")
    return mtime == int(st.st_mtime) & 0xFFFFFFFF and size == st.st_size & 0xFFFFFFFF


def _can_write(source: Path) -> bool:
    """Whether the bytecode of `source` can be written: its cache folder, or the nearest existing parent of it."""
    folder = Path(importlib.util.cache_from_source(str(source))).parent
    while not folder.exists():
        folder = folder.parent
    return os.access(folder, os.W_OK)


def survey(
    names: Iterable[str] = RUN_PACKAGES, can_write: Callable[[Path], bool] = _can_write
) -> list[PackageBytecode]:
    """Each installed package of `names`, with its sources and the stale ones among them."""
    out = []
    for name in names:
        root = package_root(name)
        if root is None:
            continue
        pkg = PackageBytecode(name, root, sources(root))
        pkg.stale = [s for s in pkg.sources if not is_fresh(s)]
        one_per_folder = {s.parent: s for s in pkg.stale}.values()  # a folder's sources share its __pycache__
        pkg.writable = all(can_write(s) for s in one_per_folder)
        out.append(pkg)
    return out


def info_line(packages: list[PackageBytecode]) -> str:
    """The `info` row: cached, or which packages lack bytecode, what it costs and the setting that helps."""
    missing = [p for p in packages if p.compiled_at_start]
    if not missing:
        return f"cached for the {len(packages)} installed packages a run imports"
    names = ", ".join(f"{p.name} ({len(p.stale)} of {len(p.sources)})" for p in missing)
    if not all(p.writable for p in missing):
        return (
            f"none for {names}, in read-only folders: every start compiles them again (seconds); "
            "set PYTHONPYCACHEPREFIX to a writable folder and unset PYTHONDONTWRITEBYTECODE"
        )
    if sys.dont_write_bytecode:
        return (
            f"none for {names}, and PYTHONDONTWRITEBYTECODE is set: every start compiles the modules it imports "
            "from them again; `fracture-gs info --warm-up` writes it once"
        )
    return f"none yet for {names}: Python writes it at the first run (or `fracture-gs info --warm-up` now)"


def compile_stale(packages: list[PackageBytecode], timeout: float = 600.0) -> tuple[int, int]:
    """Write the bytecode of every stale source of the writable `packages` with `compileall` in a child process
    (all cores; forced, since compileall alone skips a file whose mtime matches though its size changed; it
    writes whatever PYTHONDONTWRITEBYTECODE says, as pip's install step does). Returns (written,
    left stale): a source that does not compile (a template, another Python's syntax) stays stale."""
    todo = [s for p in packages if p.writable for s in p.stale]
    if not todo:
        return 0, 0
    subprocess.run(
        [sys.executable, "-m", "compileall", "-q", "-f", "-j", "0", "-i", "-"],
        input="\n".join(map(str, todo)),
        text=True,
        capture_output=True,
        timeout=timeout,
        check=False,
    )
    left = sum(not is_fresh(s) for s in todo)
    return len(todo) - left, left


def compiled_from_source(modules: Optional[dict] = None) -> tuple[int, int, list[str]]:
    """Of the source modules in `modules` (default: this process's `sys.modules`), how many have no fresh bytecode,
    so were compiled from source when imported and will be at the next start too (where Python could write it, it
    did, and they are fresh now); the total; and their top-level packages, the most such modules first."""
    counts: dict[str, int] = {}
    total = 0
    for name, module in list((sys.modules if modules is None else modules).items()):
        origin = getattr(getattr(module, "__spec__", None), "origin", None)
        if not isinstance(origin, str) or not origin.endswith(".py"):
            continue
        total += 1
        if not is_fresh(Path(origin)):
            top = name.split(".")[0]
            counts[top] = counts.get(top, 0) + 1
    tops = sorted(counts, key=lambda t: (-counts[t], t))
    return sum(counts.values()), total, tops


def profile_note(minimum: int = 20, modules: Optional[dict] = None) -> str:
    """A line for `--profile`'s report when this process compiled at least `minimum` of its modules from source
    (a few are scripts and such, which Python never caches); "" otherwise. `modules`: as `compiled_from_source`."""
    stale, total, tops = compiled_from_source(modules)
    if stale < minimum:
        return ""
    names = ", ".join(tops[:4]) + (", ..." if len(tops) > 4 else "")
    return (
        f"imports: {stale:,} of the {total:,} Python modules this run imported had no cached bytecode ({names}) and "
        "were compiled from source, as they will be at every start; `fracture-gs info` says why and "
        "`fracture-gs info --warm-up` writes it once\n"
    )
