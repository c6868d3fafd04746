"""Python's cached bytecode of what a run imports (`fracture_gs.bytecode`): found stale the way Python decides,
counted in `--profile`'s report, and written once by `info --warm-up`, also where PYTHONDONTWRITEBYTECODE is set (the
lent GPU hosts compiled torch's sources at every start: 3.8–5.4 s to import torch against 2.2–2.6 s with bytecode)."""

from __future__ import annotations

import importlib.util
import json
import os
import py_compile
import subprocess
import sys
import types
from pathlib import Path

import pytest

from fracture_gs import bytecode
from fracture_gs.cli import warm_up as cli_warm_up

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def pkg(tmp_path, monkeypatch):
    """A package `fgs_probe_pkg` with no bytecode: two modules, and one in an `include` folder (not a module a
    run imports: headers live there in torch)."""
    root = tmp_path / "fgs_probe_pkg"
    (root / "include").mkdir(parents=True)
    (root / "__init__.py").write_text("X = 1\n")
    (root / "a.py").write_text("def f():\n    return 2\n")
    (root / "include" / "skipped.py").write_text("Y = 3\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "pycache_prefix", None)
    monkeypatch.delenv("PYTHONPYCACHEPREFIX", raising=False)
    importlib.invalidate_caches()
    return root


def _stale_names(names=("fgs_probe_pkg",), **kw) -> list[str]:
    return [s.name for p in bytecode.survey(names, **kw) for s in p.stale]


def test_the_survey_finds_a_package_without_bytecode_and_the_warm_up_writes_it(pkg, monkeypatch):
    """A package with no bytecode is stale module by module (its `include` folder left out) and counts as compiled
    at every start; `compile_stale` writes both files in a child that has PYTHONDONTWRITEBYTECODE=1 (the hosts'
    setting, which only stops imports from writing), after which nothing is stale and `info` says cached."""
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    (found,) = bytecode.survey(["fgs_probe_pkg"])
    assert sorted(s.name for s in found.sources) == ["__init__.py", "a.py"]
    assert sorted(s.name for s in found.stale) == ["__init__.py", "a.py"] and found.compiled_at_start
    line = bytecode.info_line([found])
    assert "fgs_probe_pkg (2 of 2)" in line and "PYTHONDONTWRITEBYTECODE is set" in line and "--warm-up" in line
    assert bytecode.compile_stale([found]) == (2, 0)
    assert _stale_names() == []
    assert bytecode.info_line(bytecode.survey(["fgs_probe_pkg"])) == "cached for the 1 installed packages a run imports"


def test_a_changed_source_or_another_pythons_bytecode_is_stale(pkg):
    """Python recompiles a module whose source's mtime or size differs from its bytecode's header, or whose
    bytecode carries another interpreter's magic number: each of those is stale here too, and only that file."""
    bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"]))
    a, init = pkg / "a.py", pkg / "__init__.py"
    st = a.stat()
    os.utime(a, (st.st_atime, st.st_mtime + 5))  # same size, newer mtime
    assert _stale_names() == ["a.py"]
    bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"]))
    a.write_text(a.read_text().replace("2", "22"))  # size changes
    os.utime(a, (st.st_atime, st.st_mtime + 5))  # mtime as the bytecode records it
    assert _stale_names() == ["a.py"]
    bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"]))
    cached = Path(importlib.util.cache_from_source(str(init)))
    data = bytearray(cached.read_bytes())
    data[0] ^= 0xFF  # another interpreter's magic number
    cached.write_bytes(bytes(data))
    assert _stale_names() == ["__init__.py"]


def test_hash_based_bytecode_is_fresh_whatever_the_mtime(pkg):
    """A hash-based .pyc (PEP 552: what SOURCE_DATE_EPOCH builds write) records no mtime; Python checks it by the
    source's hash, so the survey does not call it stale when the source's mtime changes."""
    for name in ("__init__.py", "a.py"):
        py_compile.compile(str(pkg / name), invalidation_mode=py_compile.PycInvalidationMode.CHECKED_HASH)
    os.utime(pkg / "a.py", (1, 1))
    assert _stale_names() == []


def test_a_source_that_does_not_compile_is_left_and_does_not_count_as_a_start_cost(pkg):
    """A file this Python cannot compile (another version's syntax, as torch ships one) stays stale and is counted
    as left; the package's entry compiled, `info` does not report the package."""
    (pkg / "future.py").write_text("def f(:\n")
    written, left = bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"]))
    assert (written, left) == (2, 1)
    (found,) = bytecode.survey(["fgs_probe_pkg"])
    assert [s.name for s in found.stale] == ["future.py"] and not found.compiled_at_start
    assert bytecode.info_line([found]).startswith("cached")


def test_a_read_only_package_is_reported_and_not_written(pkg):
    """Where the bytecode's folder cannot be written, the warm-up writes nothing there and `info` names the
    setting that helps (a writable PYTHONPYCACHEPREFIX) instead of the warm-up."""
    packages = bytecode.survey(["fgs_probe_pkg"], can_write=lambda folder: False)
    assert not packages[0].writable
    assert bytecode.compile_stale(packages) == (0, 0)
    assert _stale_names() == ["__init__.py", "a.py"]
    line = bytecode.info_line(packages)
    assert "read-only" in line and "PYTHONPYCACHEPREFIX" in line and "--warm-up" not in line


def test_a_pycache_prefix_is_where_bytecode_is_read_and_written(pkg, tmp_path, monkeypatch):
    """With PYTHONPYCACHEPREFIX, Python reads and writes bytecode under that folder only: the survey looks there,
    and the warm-up's child writes there, not beside the sources."""
    prefix = tmp_path / "pyc"
    monkeypatch.setenv("PYTHONPYCACHEPREFIX", str(prefix))
    monkeypatch.setattr(sys, "pycache_prefix", str(prefix))
    assert bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"])) == (2, 0)
    assert not (pkg / "__pycache__").exists() and len(list(prefix.rglob("*.pyc"))) == 2
    assert _stale_names() == []
    monkeypatch.setattr(sys, "pycache_prefix", None)
    assert _stale_names() == ["__init__.py", "a.py"]  # beside the sources there is still none


def test_without_the_setting_python_writes_it_at_the_first_run(pkg, monkeypatch):
    """Without PYTHONDONTWRITEBYTECODE, missing bytecode is a first-run cost only, and `info` says so."""
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    line = bytecode.info_line(bytecode.survey(["fgs_probe_pkg"]))
    assert "first run" in line and "PYTHONDONTWRITEBYTECODE" not in line


def test_the_warm_up_step_compiles_once_then_finds_it_cached(pkg, monkeypatch):
    """`info --warm-up`'s bytecode step writes what is missing and says how many; run again it says cached."""
    monkeypatch.setattr(bytecode, "imported_packages", lambda: ("fgs_probe_pkg",))
    first = cli_warm_up.bytecode_step()
    assert first.status == "2 module(s) compiled", first
    assert cli_warm_up.bytecode_step().status == "cached"


def test_a_single_module_distribution_is_its_own_entry(tmp_path, monkeypatch):
    """typing_extensions and plyfile are one file each: that file is the package's sources and its entry."""
    (tmp_path / "fgs_probe_mod.py").write_text("Z = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "pycache_prefix", None)
    importlib.invalidate_caches()
    (found,) = bytecode.survey(["fgs_probe_mod", "fgs_not_installed_anywhere"])
    assert found.sources == [tmp_path / "fgs_probe_mod.py"] and found.compiled_at_start


def test_the_run_packages_cover_what_a_run_imports(tmp_path):
    """Every top-level package outside the standard library that a CPU render-sim run imports is in
    `RUN_PACKAGES`, so `info` checks and the warm-up compiles what a run would compile at its start. (A GPU run
    adds gsplat and what it imports; those are listed too, and the warm-up adds whatever its own gsplat step
    imported.)"""
    script = (
        "import atexit, json, sys\n"
        "def dump():\n"
        "    tops = {m.split('.')[0] for m in list(sys.modules)} - set(sys.stdlib_module_names)\n"
        "    print('TOPS ' + json.dumps(sorted(t for t in tops if not t.startswith('_'))), file=sys.stderr)\n"
        "atexit.register(dump)\n"
        "from fracture_gs.cli import main\n"
        "sys.argv = ['fracture-gs', 'render-sim', 'bread', '--frames', '2', '--particles', '300',\n"
        f"            '--resolution', '64x48', '--schedule', 'in-turn', '--out', {str(tmp_path / 'run')!r}]\n"
        "sys.exit(main())\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    tops = json.loads(next(ln for ln in out.stderr.splitlines() if ln.startswith("TOPS "))[5:])
    assert "torch" in tops and "warp" in tops  # the probe saw the run
    assert set(tops) - set(bytecode.RUN_PACKAGES) == set()


def test_the_profile_counts_the_modules_compiled_from_source(pkg):
    """`--profile`'s note counts the imported source modules without fresh bytecode by top-level package (they were
    compiled at this start and will be at the next), says what helps, and is silent below its threshold or once
    the bytecode is written."""
    mods = {}
    for name, path in (("fgs_probe_pkg", pkg / "__init__.py"), ("fgs_probe_pkg.a", pkg / "a.py")):
        module = types.ModuleType(name)
        module.__spec__ = importlib.util.spec_from_file_location(name, path)
        mods[name] = module
    mods["builtin_like"] = types.ModuleType("builtin_like")  # no source file: not counted
    assert bytecode.compiled_from_source(mods) == (2, 2, ["fgs_probe_pkg"])
    note = bytecode.profile_note(minimum=2, modules=mods)
    assert "2 of the 2 Python modules" in note and "(fgs_probe_pkg)" in note and "info --warm-up" in note
    assert bytecode.profile_note(minimum=3, modules=mods) == ""
    bytecode.compile_stale(bytecode.survey(["fgs_probe_pkg"]))
    assert bytecode.compiled_from_source(mods) == (0, 2, [])
