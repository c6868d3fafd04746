"""The mutation picker (`mutation/pick_tests.py`) for a module that no test calls into.

`sim/storage.py` is an interface of abstract methods and a few constants: every line of it runs at import, while
pytest collects, outside any test's coverage context, so the coverage map holds no line of it. Its mutants must still
run the test files that name the module (and the files `targets.toml` lists for it); before, they ran nothing and
all four of a sample's storage mutants were recorded as survivors, one of them a mutant that cannot even be imported.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "mutation"))
import pick_tests  # noqa: E402


def test_a_module_without_a_map_runs_the_tests_that_name_it(monkeypatch):
    """A constant of `sim/storage.py` (MAX_SLOTS, the counters) and an abstract method's default, with an empty
    coverage map: the picker selects the test files that import `fracture_gs.sim.storage`, this round's contract
    test among them, and no file that does not name it."""
    monkeypatch.chdir(ROOT)
    module = "fracture_gs/sim/storage.py"
    source = (ROOT / module).read_text()
    lines = source.splitlines()
    for text in ("MAX_SLOTS = 8", "COUNT_CLAMPED, COUNT_ESCAPED", "def g2p(self, only_fragment: int = -1)"):
        line = next(i for i, ln in enumerate(lines, 1) if text in ln)
        picked = pick_tests.select_tests(module, [line], source, {}, {})
        assert "tests/test_pinned_sim_5_storage_contract.py" in picked, text
        for test in picked:
            assert "sim.storage" in (ROOT / test).read_text() or "import storage" in (ROOT / test).read_text(), test


def test_a_constant_of_an_unmapped_module_also_runs_its_listed_tests(tmp_path, monkeypatch):
    """A toy constants-only module with no map line: its constant's mutant runs the files naming it and the ones
    targets.toml lists; a module with a map keeps the map's callers and never adds the list."""
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_names_it.py").write_text("from pkg.limits import LIMIT\n")
    (tmp_path / "tests" / "test_other.py").write_text("import os\n")
    monkeypatch.chdir(tmp_path)
    source = "LIMIT = 3\n"
    fallback = {"pkg/limits.py": ["tests/test_kernels.py"]}
    got = pick_tests.select_tests("pkg/limits.py", [1], source, {}, fallback)
    assert got == ["tests/test_names_it.py", "tests/test_kernels.py"]
    source = "LIMIT = 3\n\n\ndef f(x):\n    return min(x, LIMIT)\n"
    cover = {"pkg/limits.py": {"5": ["tests/t.py::test_f"]}}
    got = pick_tests.select_tests("pkg/limits.py", [1], source, cover, fallback)
    assert got == ["tests/t.py::test_f", "tests/test_names_it.py"]
