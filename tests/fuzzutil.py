"""Shared by the property-based suites (tests/test_fuzz_*.py): a tally of inputs tried per category and
outcome, printed at the end of each suite so CI logs show what was tried, and the suite's settings."""

from __future__ import annotations

import os
from collections import Counter

from hypothesis import HealthCheck, settings

OUTCOMES = ("clean load", "our error", "traceback", "silent acceptance", "false rejection")


def fuzz_settings(examples: int) -> settings:
    """Bounded by example count (FGS_FUZZ_SCALE multiplies it for a longer local hunt), no deadline
    (Warp's first-use compile), no example database (CI starts fresh)."""
    scale = float(os.environ.get("FGS_FUZZ_SCALE", "1"))
    return settings(
        max_examples=max(1, int(examples * scale)),
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


class Tally:
    """Counts per (category, outcome); `report` prints one line per category and returns the totals."""

    def __init__(self, suite: str):
        self.suite = suite
        self.counts: dict[str, Counter] = {}

    def add(self, category: str, outcome: str) -> None:
        assert outcome in OUTCOMES, outcome
        self.counts.setdefault(category, Counter())[outcome] += 1

    def total(self, outcome: str | None = None) -> int:
        return sum(c[outcome] if outcome else sum(c.values()) for c in self.counts.values())

    def report(self, capsys) -> str:
        lines = [f"fuzz {self.suite}: {self.total()} inputs"]
        for category, c in sorted(self.counts.items()):
            parts = ", ".join(f"{c[o]} {o}" for o in OUTCOMES)
            lines.append(f"  {category:<40} {sum(c.values()):>5} inputs: {parts}")
        text = "\n".join(lines)
        with capsys.disabled():
            print("\n" + text)
        return text


def run_cli(main, argv: list, capsys, tally: Tally, category: str) -> tuple[int, str, str]:
    """Run the CLI in-process on `argv`: an exception out of it is tallied as a traceback and re-raised, no output
    may hold a traceback, and exit 2 must be the one line `fracture-gs: error: ...`. Returns (code, err, that
    line or "")."""
    try:
        code = main(argv)
    except BaseException:
        tally.add(category, "traceback")
        raise
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err, err
    line = ""
    if code == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("fracture-gs: error: "), err
        line = lines[0]
    return code, err, line


def ok_summary(cfg, variants, device):
    """What a stand-in for `render_sim.run_render_sim` returns: every variant `ok`, nothing simulated."""
    from fracture_gs.render_sim import RunSummary

    rows = [{"variant": v, "status": "ok"} for v in variants]
    return RunSummary(cfg.name, cfg.scene, cfg.preset, device, 1, [], 1, 0.01, rows)
