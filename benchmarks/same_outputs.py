"""Whether two render-sim output folders hold the same bytes, wall-clock fields aside (issue 36: a speed-up must not
change a number). Every file is compared byte for byte except summary.json (compared as JSON without `wall_s`,
`substeps_per_s`, `profile` and `out_dir`), summary.md (without its last column, substeps/s) and profile.md.

    python benchmarks/same_outputs.py runs/before runs/after     # prints "identical: N files" or each difference

Exit status 0 when identical, 1 otherwise.
"""

from __future__ import annotations

import filecmp
import json
import re
import sys
from pathlib import Path

TIMINGS = {"wall_s", "substeps_per_s", "profile", "out_dir"}
SKIPPED = {"profile.md", "summary.md", "summary.json"}


def _without_timings(value):
    if isinstance(value, dict):
        return {k: _without_timings(v) for k, v in value.items() if k not in TIMINGS}
    if isinstance(value, list):
        return [_without_timings(v) for v in value]
    return value


def _table_rows(path: Path) -> list[str]:
    """summary.md's lines, each table row without its last cell (substeps/s)."""
    return [re.sub(r"\|[^|]*\|\s*$", "|", line) for line in path.read_text().splitlines()]


def differences(a: Path, b: Path) -> list[str]:
    """What differs between run folders a and b (empty: the same run)."""
    files_a = {p.relative_to(a).as_posix() for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b).as_posix() for p in b.rglob("*") if p.is_file()}
    out = [f"only in {a if f in files_a else b}: {f}" for f in sorted(files_a ^ files_b) if f != "profile.md"]
    for f in sorted(files_a & files_b):
        if f in SKIPPED:
            continue
        if not filecmp.cmp(a / f, b / f, shallow=False):
            out.append(f"{f} differs")
    if "summary.json" in files_a & files_b:
        ja, jb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
        if _without_timings(ja) != _without_timings(jb):
            out.append("summary.json differs beyond its timings")
    if "summary.md" in files_a & files_b and _table_rows(a / "summary.md") != _table_rows(b / "summary.md"):
        out.append("summary.md differs beyond its substeps/s column")
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python benchmarks/same_outputs.py RUN_A RUN_B", file=sys.stderr)
        return 2
    a, b = Path(argv[0]), Path(argv[1])
    for d in (a, b):
        if not d.is_dir():
            print(f"{d} is not a folder", file=sys.stderr)
            return 2
    found = differences(a, b)
    n = sum(1 for p in a.rglob("*") if p.is_file())
    print("\n".join(found) if found else f"identical: {n} files")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
