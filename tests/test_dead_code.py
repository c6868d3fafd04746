"""The code keeps no dead code and its typed core type-checks.

vulture (configured in pyproject.toml's [tool.vulture]) reads `fracture_gs/`, `examples/` and `benchmarks/`
and reports any function, class, attribute or variable that nothing uses; the names Python, a library or a
user calls are listed with their reason in tests/dead_code_allowlist.py. mypy (pyproject.toml's
[tool.mypy]) checks the configuration, the variants and the render-sim job, where a wrong type would
otherwise travel far before it fails."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(module: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", module, *args], cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_vulture_finds_no_unused_code():
    """Every function, class, attribute and variable of the package, examples and benchmarks is used (or listed
    in the allowlist with why): code that nothing calls is removed, not kept to rot."""
    out = _run("vulture")
    fix = "unused code: remove it, or list it with its reason in tests/dead_code_allowlist.py"
    assert out.returncode == 0 and not out.stdout.strip(), f"{fix}\n{out.stdout}{out.stderr[-2000:]}"


def test_vulture_sees_a_planted_dead_function(tmp_path):
    """The check above can fail: a module with a function nothing calls is reported."""
    (tmp_path / "m.py").write_text("def used():\n    return 1\n\n\ndef never_called():\n    return 2\n\n\nused()\n")
    out = _run("vulture", str(tmp_path / "m.py"), "--min-confidence", "60")
    assert out.returncode != 0 and "never_called" in out.stdout


@pytest.mark.slow
def test_typed_modules_type_check():
    """The config dataclasses, the variants and the render-sim job pass mypy: a field set to the wrong type, a
    None used as a value or a call with the wrong arguments is caught before it runs."""
    out = _run("mypy")
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]
