"""The test command cosmic-ray runs for one mutant: find what changed, run only the tests that reach it.

cosmic-ray applies a mutant to a file on disk and runs one fixed command; this is that command. It
compares every target file with the pristine copy `run.py` saved, takes the changed lines, and runs

* the tests that executed those lines (the coverage map `run.py map` recorded per test), or
* for a line no Python tracer can see (the body of a `@wp.kernel` / `@wp.func`, compiled by Warp),
  the test files `targets.toml` lists for that module.

Exit status is pytest's: 0 means every selected test passed, so the mutant survived. A changed line
that no test reaches runs nothing and survives; that is the honest answer.
"""

from __future__ import annotations

import difflib
import json
import os
import subprocess
import sys
from pathlib import Path

import tomllib

HERE = Path(__file__).resolve().parent
STATE = HERE / ".state"


def changed_lines(original: str, mutated: str) -> list[int]:
    """1-based line numbers of `original` that the mutant rewrote (one mutant touches one or two lines)."""
    a, b = original.splitlines(), mutated.splitlines()
    lines: list[int] = []
    for tag, i1, i2, _, _ in difflib.SequenceMatcher(a=a, b=b, autojunk=False).get_opcodes():
        if tag != "equal":
            lines.extend(range(i1 + 1, max(i2, i1 + 1) + 1))
    return lines


def kernel_lines(source: str) -> set[int]:
    """Lines inside functions Warp compiles: decorated (`@wp.kernel`, `@wp.func`, ...) or built by a factory that
    passes the function to a Warp call (`return wp.kernel(box_p2g_runs, name=...)`)."""
    import ast

    tree = ast.parse(source)
    built = {
        call.args[0].id
        for call in ast.walk(tree)
        if isinstance(call, ast.Call) and call.args and isinstance(call.args[0], ast.Name)
        if ast.unparse(call.func).startswith("wp.")
    }
    out: set[int] = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef):
            continue
        if node.name in built or any("wp." in ast.unparse(d) for d in node.decorator_list):
            out.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return out


def function_lines(source: str) -> set[int]:
    """Lines inside function bodies: they run when called. Every other line (module constants, defaults, class
    bodies, dataclass fields) runs once, at import, and coverage credits it to whichever test imported it first."""
    import ast

    out: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            out.update(range(node.body[0].lineno, (node.end_lineno or node.lineno) + 1))
    return out


def importers(module: str, tests_dir: Path = Path("tests")) -> list[str]:
    """Test files that name `module` (`fracture_gs.capture.materials`, `capture.materials`, `import materials`): a
    test that only reads a module's constants executes none of its functions, so coverage does not tie it to them."""
    import re

    parts = module.removesuffix(".py").split("/")
    names = [re.escape(".".join(parts[-k:])) + r"\b" for k in range(2, len(parts) + 1)]
    pattern = re.compile("|".join([*names, r"\bimport " + re.escape(parts[-1]) + r"\b"]))
    if not tests_dir.is_dir():
        return []
    return [str(p) for p in sorted(tests_dir.glob("test_*.py")) if pattern.search(p.read_text())]


def select_tests(module: str, lines: list[int], source: str, cover: dict, fallback: dict) -> list[str]:
    """Test node ids (or files) that exercise `lines` of `module`: coverage for lines in function bodies, every test
    that calls into the module for a line run at import, the static list for kernels."""
    kern = kernel_lines(source)
    by_line = cover.get(module, {})
    called = function_lines(source)
    picked: dict[str, None] = {}
    for line in lines:
        if line not in called and line not in kern:  # an import-time line: the module's users
            users = {t for n, ts in by_line.items() if int(n) in called and int(n) not in kern for t in ts}
            # and the test files that read its data by name; a module no test calls into (an interface whose
            # methods are abstract, a table of constants) has no map, so those and the listed tests are all it gets
            listed = [] if by_line else fallback.get(module, [])
            for test in sorted(users) + importers(module) + listed:
                picked[test] = None
            continue
        if line in kern or not by_line:
            for test in fallback.get(module, []):
                picked[test] = None
        tests = by_line.get(str(line))
        if tests is None and line not in kern:  # a line written after the map: the tests of its neighbours
            near = [by_line[str(n)] for d in range(1, 6) for n in (line - d, line + d) if str(n) in by_line]
            tests = near[0] + (near[1] if len(near) > 1 else []) if near else []
        for test in tests or []:
            picked[test] = None
    return list(picked)


def load_fallback() -> dict[str, list[str]]:
    spec = tomllib.loads((HERE / "targets.toml").read_text())
    return {t["module"]: t.get("tests", []) for t in spec.get("target", [])}


def main() -> int:
    manifest = json.loads((STATE / "manifest.json").read_text())
    cover_path = STATE / "coverage_map.json"
    cover = json.loads(cover_path.read_text()) if cover_path.exists() else {}
    fallback = load_fallback()
    root = Path.cwd()
    tests: list[str] = []
    for module in manifest:
        now = (root / module).read_text()
        before = (STATE / "orig" / module).read_text()
        if now != before:
            tests += select_tests(module, changed_lines(before, now), before, cover, fallback)
    tests = [t for t in dict.fromkeys(tests) if (root / t.split("::")[0]).exists()]
    timing_path = STATE / "durations.json"
    if timing_path.exists():  # fastest first: a killed mutant stops at its first failing test (-x)
        seconds = json.loads(timing_path.read_text())
        tests.sort(key=lambda t: seconds.get(t, seconds.get(t.split("::")[0], 1.0)))
    if not tests:
        print("no test reaches the mutated line: survived")
        return 0
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "--no-header"]
    run = subprocess.run(cmd + tests, env=env, cwd=root, capture_output=True, text=True)
    sys.stdout.write(run.stdout + run.stderr)
    files = by_file_retry(run.returncode, run.stdout + run.stderr, tests)
    if files:  # one node id the map recorded is not collected here: run their files rather than nothing
        print(f"a selected test id was not found: running its {len(files)} file(s) instead")
        run = subprocess.run(cmd + files, env=env, cwd=root, capture_output=True, text=True)
        sys.stdout.write(run.stdout + run.stderr)
    return outcome(run.returncode, run.stdout + run.stderr)


def by_file_retry(rc: int, output: str, tests: list[str]) -> list[str]:
    """The selected tests' files, when pytest refused the whole selection because one node id was not found (exit
    4, "not found": a parametrised id that changed since the map, or that the map wrote differently); pytest then
    runs no test at all, and the mutant would count as survived though its tests were never run. Else []."""
    if rc != 4 or "not found" not in output or "ERROR collecting" in output:
        return []
    return list(dict.fromkeys(t.split("::")[0] for t in tests))


def outcome(rc: int, output: str) -> int:
    """pytest's exit status → ours (0: the mutant survived). 4 and 5 (nothing collected, a node id not found)
    kill nothing, unless a test module failed to import: then the mutant broke it (a module-level call into the
    mutated code), which is a kill, though pytest reports the selected node ids as not found."""
    if rc in (4, 5):
        return 1 if "ERROR collecting" in output else 0
    return rc


if __name__ == "__main__":
    sys.exit(main())
