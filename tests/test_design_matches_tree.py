"""docs/DESIGN.md's architecture matches the tree: every package and module its Architecture section and its
"sim/ by role" tree name exists, and every package of `fracture_gs` is named there, so a newcomer reading the
design finds the code where it says and no package is left out of it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "fracture_gs"
DESIGN = (ROOT / "docs" / "DESIGN.md").read_text()


def _section(title: str) -> str:
    start = DESIGN.index(f"## {title}")
    end = DESIGN.find("\n## ", start + 3)
    return DESIGN[start : end if end > 0 else None]


def _names(text: str) -> set[str]:
    """Every `name/` or `name.py` (backticked, in table rows or in a code block's words)."""
    words = set(re.findall(r"`([A-Za-z_][\w/]*(?:/|\.py))`", text))
    for block in re.findall(r"```\n(.*?)```", text, flags=re.S):
        words |= set(re.findall(r"(?<![\w./-])([A-Za-z_]\w*(?:/|\.py))(?=[\s,)]|$)", block, flags=re.M))
    return words


def _exists(name: str, base: Path) -> bool:
    for root in (base, PKG, ROOT):
        if (root / name.rstrip("/")).exists():
            return True
    return any(p.name == name.rstrip("/") for p in PKG.rglob(name.rstrip("/")))


def test_every_name_in_the_architecture_exists():
    """The Architecture section's packages and modules are all in the tree (a moved or removed module is a
    sentence to rewrite, not a stale pointer)."""
    missing = sorted(n for n in _names(_section("Architecture")) if not _exists(n, PKG))
    assert not missing, f"docs/DESIGN.md's Architecture names what the tree lacks: {missing}"


def test_the_sim_tree_in_the_design_is_the_sim_tree():
    """The "sim/ by role" tree lists files and folders of `fracture_gs/sim` that exist."""
    missing = sorted(n for n in _names(_section("sim/ by role")) if not _exists(n, PKG / "sim"))
    assert not missing, f"docs/DESIGN.md's sim tree names what fracture_gs/sim lacks: {missing}"


def test_every_package_is_named_in_the_architecture():
    """Each top-level package and module of `fracture_gs` appears in the Architecture section."""
    text = _section("Architecture")
    top = [p.name + "/" for p in PKG.iterdir() if (p / "__init__.py").exists()]
    top += [p.name for p in PKG.glob("*.py") if p.name not in ("__init__.py", "__main__.py")]
    unnamed = sorted(n for n in top if n not in text)
    assert not unnamed, f"docs/DESIGN.md's Architecture does not name: {unnamed}"


def test_the_check_sees_a_missing_module():
    """The name reader finds backticked modules and code-block words, so a stale name would fail the tests above."""
    assert {"sim/", "nowhere.py"} <= _names("`sim/` and `nowhere.py`\n```\nsim/  nowhere.py\n```\n")
    assert not _exists("nowhere.py", PKG)
