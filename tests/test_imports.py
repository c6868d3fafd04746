"""The package's structure: every import points down into `fracture_gs` (never out to `examples/` or
`benchmarks/`, never round in a cycle), one file holds one idea (≤ 600 lines), and importing the package changes nothing
in the process (Warp stays uninitialised with its global config untouched; stderr stays stderr)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "fracture_gs"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(current: str, is_pkg: bool, node: ast.ImportFrom) -> list[str]:
    """Absolute names a `from ... import ...` can load: the module and each name as a submodule."""
    if node.level:
        base = current.split(".") if is_pkg else current.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        mod = ".".join(base + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    return [mod] + [f"{mod}.{a.name}" for a in node.names]


def import_graph() -> dict[str, set[str]]:
    """module -> the package modules it imports anywhere in its body (lazy imports included)."""
    files = {_module_name(p): p for p in PKG.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                targets.update(_resolve(name, path.name == "__init__.py", node))
        graph[name] = targets
    return graph


@pytest.mark.slow
def test_no_module_of_the_package_imports_examples_or_benchmarks():
    outside = ("examples", "benchmarks")
    bad = {m: sorted(t for t in ts if t.split(".")[0] in outside) for m, ts in import_graph().items()}
    assert not {m: t for m, t in bad.items() if t}, "the package must not import examples/ or benchmarks/"
    for path in PKG.rglob("*.py"):
        assert "sys.path" not in path.read_text(), f"{path.name} edits sys.path"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Elementary cycles found by depth-first search (one per back edge), over edges inside the
    package; an import of a package's own submodule from its __init__ is not a cycle."""
    edges = {m: sorted(t for t in ts if t in graph and t != m and not t.startswith(m + ".")) for m, ts in graph.items()}
    found, state, stack = [], {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for t in edges[m]:
            if state.get(t) == 1:
                found.append(stack[stack.index(t) :] + [t])
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    return found


def test_import_graph_has_no_cycle():
    """Lazy (function-level) imports count too: a cycle there is still two modules that need each other."""
    assert _cycles(import_graph()) == []


def test_the_cycle_finder_finds_cycles():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c", "a"]]
    assert _cycles({"p": {"p.x"}, "p.x": {"q"}, "q": set()}) == []


def test_one_idea_per_file():
    long = {p.name: n for p in PKG.rglob("*.py") if (n := len(p.read_text().splitlines())) > 600}
    assert long == {}, f"files over 600 lines: {long}"


IMPORT_EVERYTHING = """
import os, sys
import warp as wp
before = {k: v for k, v in vars(wp.config).items() if not k.startswith("_")}
fd_before = os.fstat(2)
import pkgutil, importlib, fracture_gs
names = [m.name for m in pkgutil.walk_packages(fracture_gs.__path__, "fracture_gs.") if not m.name.endswith("__main__")]
for name in names:
    importlib.import_module(name)
after = {k: v for k, v in vars(wp.config).items() if not k.startswith("_")}
changed = {k for k in before if before[k] != after.get(k)}
from warp._src.context import runtime
assert runtime is None, "Warp was initialised by an import"
assert not changed, f"wp.config changed by an import: {sorted(changed)}"
fd_after = os.fstat(2)
assert (fd_before.st_ino, fd_before.st_dev) == (fd_after.st_ino, fd_after.st_dev), "stderr was redirected"
print(len(names))
"""


@pytest.mark.slow
def test_importing_every_module_has_no_side_effects():
    out = subprocess.run(
        [sys.executable, "-c", IMPORT_EVERYTHING], capture_output=True, text=True, cwd=PKG.parent, timeout=300
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert int(out.stdout.split()[-1]) > 40
