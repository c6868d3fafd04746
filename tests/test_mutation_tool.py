"""The mutation tool (mutation/run.py, mutation/pick_tests.py) scores what it claims: a mutant a test
catches is killed, one no test can tell apart survives, and each mutant runs the tests that reach its line."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

MUTATION = Path(__file__).resolve().parent.parent / "mutation"
sys.path.insert(0, str(MUTATION))
import pick_tests  # noqa: E402


def test_changed_lines_are_the_rewritten_ones():
    """A one-token mutant on line 3 of five reports line 3 and nothing else."""
    before = "a = 1\nb = 2\nif a > b:\n    pass\nc = 3\n"
    after = before.replace("a > b", "a >= b")
    assert pick_tests.changed_lines(before, after) == [3]


def test_kernel_bodies_fall_back_to_the_listed_tests_and_host_lines_to_coverage():
    """A line inside a `@wp.kernel` is invisible to the tracer, so its tests come from targets.toml;
    a host line gets exactly the tests coverage saw on it, a line written after the map its neighbours' tests."""
    src = "import warp as wp\n\n@wp.kernel\ndef k(x: wp.array(dtype=float)):\n    x[0] = 1.0\n\n"
    src += "def host():\n    return 2\n"
    assert pick_tests.kernel_lines(src) == {4, 5}
    cover = {"m.py": {"8": ["tests/t.py::test_host"]}}
    fallback = {"m.py": ["tests/test_kernels.py"]}
    assert pick_tests.select_tests("m.py", [5], src, cover, fallback) == ["tests/test_kernels.py"]
    assert pick_tests.select_tests("m.py", [8], src, cover, fallback) == ["tests/t.py::test_host"]
    # a line the map has not seen (written after it) takes its neighbours' tests; one far from any gets none
    assert pick_tests.select_tests("m.py", [7], src, cover, fallback) == ["tests/t.py::test_host"]
    assert pick_tests.select_tests("m.py", [8], src, {"m.py": {"20": ["tests/t.py::test_far"]}}, fallback) == []
    # a module constant runs at import, credited to whichever test imported first: it gets every test that calls in
    const = "LIMIT = 3\n\n\ndef f(x):\n    return min(x, LIMIT)\n"
    cover = {"c.py": {"1": ["tests/a.py::test_first_import"], "5": ["tests/b.py::test_f", "tests/c.py::test_g"]}}
    assert pick_tests.select_tests("c.py", [1], const, cover, {}) == ["tests/b.py::test_f", "tests/c.py::test_g"]


def test_a_kernel_built_by_a_factory_is_a_kernel_line():
    """A kernel compiled from a nested function (`return wp.kernel(body, name=...)`) is as invisible to the tracer
    as a decorated one, so its body takes the listed tests; the factory's own host lines stay coverage's."""
    src = "import warp as wp\n\n\ndef make(flag):\n    def body(x: wp.array(dtype=float)):\n"
    src += "        x[0] = 1.0\n\n    return wp.kernel(body, name='b')\n"
    assert pick_tests.kernel_lines(src) == {5, 6}
    fallback = {"m.py": ["tests/test_kernels.py"]}
    assert pick_tests.select_tests("m.py", [6], src, {"m.py": {"8": ["tests/t.py::test_make"]}}, fallback) == [
        "tests/test_kernels.py"
    ]


def test_every_module_with_warp_kernels_lists_its_tests():
    """Every package module that Warp compiles code from has a targets.toml entry naming test files that exist:
    without one, a mutant inside its kernels runs no test and counts as a survivor the suite never saw."""
    root = Path(__file__).resolve().parents[1]
    listed = pick_tests.load_fallback()
    for path in sorted((root / "fracture_gs").rglob("*.py")):
        module = str(path.relative_to(root))
        if pick_tests.kernel_lines(path.read_text()):
            assert listed.get(module), f"{module} has Warp kernels but no [[target]] in mutation/targets.toml"
            for test in listed[module]:
                assert (root / test).is_file(), f"targets.toml lists {test} for {module}, which does not exist"


@pytest.mark.slow
def test_a_toy_session_kills_what_its_test_catches_and_keeps_the_equivalent(tmp_path):
    """End to end on a toy package: `v > vmax` → `v < vmax` changes clamp_speed(2, 1) and is killed;
    `v > vmax` → `v >= vmax` returns vmax at v == vmax either way, so it survives; the score says 2 of 3."""
    shutil.copytree(MUTATION, tmp_path / "mutation", ignore=shutil.ignore_patterns(".state", "__pycache__"))
    (tmp_path / "fracture_gs").mkdir()
    (tmp_path / "fracture_gs" / "__init__.py").write_text("")
    (tmp_path / "fracture_gs" / "toy.py").write_text(
        "def clamp_speed(v, vmax):\n    if v > vmax:\n        return vmax\n    return v\n"
    )
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_toy.py").write_text(
        "from fracture_gs.toy import clamp_speed\n\n\ndef test_clamp():\n"
        "    assert clamp_speed(2.0, 1.0) == 1.0 and clamp_speed(0.5, 1.0) == 0.5\n"
    )
    run = [sys.executable, "mutation/run.py"]
    subprocess.run([*run, "map", "--jobs", "1"], cwd=tmp_path, check=True, capture_output=True, timeout=300)
    out = subprocess.run(
        [*run, "run", "fracture_gs/toy.py", "--timeout", "60"],
        cwd=tmp_path,
        check=True,
        capture_output=True,
        text=True,
        timeout=600,
    ).stdout
    assert "3 to run" in out and "66.7%" in out
    survivors = json.loads((tmp_path / "mutation" / ".state" / "survivors.json").read_text())
    assert [s["operator"] for s in survivors] == ["core/ReplaceComparisonOperator_Gt_GtE"]


def test_every_equivalent_mutant_names_a_line_that_exists_and_a_reason():
    """equivalent.toml leaves survivors out of the score, so each entry must be checkable: it parses, names a module,
    an operator and a reason, and its line is in that module today (a stale entry would excuse nothing, or the
    wrong line)."""
    import tomllib

    root = MUTATION.parent
    entries = tomllib.loads((MUTATION / "equivalent.toml").read_text())["mutant"]
    assert entries
    for e in entries:
        assert {"module", "operator", "line", "reason"} <= set(e), e
        source = [ln.strip() for ln in (root / e["module"]).read_text().splitlines()]
        assert e["line"].strip() in source, f"{e['module']}: no line {e['line']!r}"
        assert len(e["reason"]) > 20, e


def test_a_mutant_that_breaks_a_test_modules_import_is_killed():
    """A mutant that makes a selected test module fail to import (a module-level call into the mutated code)
    is killed, although pytest then exits 4 ("found no collectors"); a selection pytest cannot find with no
    collection error (a stale node id) or nothing collected still counts as survived, and pytest's own 0/1 pass
    through."""
    broken = "ERROR collecting tests/test_fuzz_config.py\nERROR: found no collectors for tests/t.py::test_x\n"
    assert pick_tests.outcome(4, broken) == 1
    assert pick_tests.outcome(4, "ERROR: not found: tests/t.py::test_gone\n") == 0
    assert pick_tests.outcome(5, "no tests ran\n") == 0
    assert (pick_tests.outcome(0, "1 passed"), pick_tests.outcome(1, "1 failed")) == (0, 1)


def test_a_selection_pytest_cannot_find_is_rerun_by_file():
    """pytest runs nothing when one selected node id is not found (exit 4): the picker then runs the selected tests'
    files, once each, so a mutant is never counted as survived by tests that did not run; a module that failed to
    import (a kill) and a normal run are left as they are."""
    tests = ["tests/a.py::test_x[p1]", "tests/a.py::test_y", "tests/b.py::test_z"]
    assert pick_tests.by_file_retry(4, "ERROR: not found: tests/a.py::test_x[p1]\n", tests) == [
        "tests/a.py",
        "tests/b.py",
    ]
    assert pick_tests.by_file_retry(4, "ERROR collecting tests/a.py\nERROR: not found: x\n", tests) == []
    assert pick_tests.by_file_retry(1, "1 failed", tests) == []
    assert pick_tests.by_file_retry(0, "3 passed", tests) == []


@pytest.mark.slow
def test_a_shard_that_dies_is_mapped_again_file_by_file(tmp_path):
    """A test file that kills its pytest process (here `os.abort()`, as a fatal error in an extension would) leaves
    its shard without coverage data. The map runs that shard's files again one a process: the file sharing the
    dead shard is mapped, the dying one is listed in map_gaps.json and named on the way out, and `map` exits 1."""
    shutil.copytree(MUTATION, tmp_path / "mutation", ignore=shutil.ignore_patterns(".state", "__pycache__"))
    (tmp_path / "fracture_gs").mkdir()
    (tmp_path / "fracture_gs" / "__init__.py").write_text("")
    (tmp_path / "fracture_gs" / "toy.py").write_text("def double(v):\n    return 2 * v\n")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_a_toy.py").write_text(
        "from fracture_gs.toy import double\n\n\ndef test_double():\n    assert double(2) == 4\n"
    )
    (tmp_path / "tests" / "test_b_dies.py").write_text("import os\n\n\ndef test_dies():\n    os.abort()\n")
    done = subprocess.run(
        [sys.executable, "mutation/run.py", "map", "--jobs", "1"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    state = tmp_path / "mutation" / ".state"
    assert json.loads((state / "map_gaps.json").read_text()) == ["tests/test_b_dies.py"]
    assert "NOT in the map" in done.stdout and "tests/test_b_dies.py" in done.stdout
    cov = json.loads((state / "coverage_map.json").read_text())
    assert cov["fracture_gs/toy.py"]["2"] == ["tests/test_a_toy.py::test_double"]
