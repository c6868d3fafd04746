"""The repository stands alone (issue 35, item 5): no stale timings in the package's docstrings and comments, no
paths into a sibling folder outside the repository, a short BENCHMARKS.md, and relative links that resolve."""

from __future__ import annotations

import ast
import io
import re
import subprocess
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "fracture_gs"
BENCHMARKS_MAX_LINES = 400

CARD = re.compile(
    r"\b(?:GH200|H100|H200|H800|A100|A800|A10G?|V100|L40S?|B200|RTX[ -]?\w+|MI[23]\d\dX?|Hopper|Ampere|sm_\d{2,3})\b"
)
"""A GPU named by model or architecture (the measurement is then only true of that card)."""
TIMING = re.compile(r"(?<![\w.])\d+(?:\.\d+)?\s?(?:µs|us|ms)\b")
"""A duration in micro- or milliseconds written as a number: `0.35 µs`, `63 ms`, `5ms` (not `time step in s`)."""
NEAR = 160
"""Characters between a timing and a card name within one docstring or comment block for them to belong together."""

OUTSIDE = ".." + "/shared"  # spelled in two parts so this file does not mention it


def card_timings(text: str) -> list[str]:
    """The timings in `text` that have a card name within NEAR characters: a measurement on a named card."""
    cards = [m.start() for m in CARD.finditer(text)]
    return [m.group(0) for m in TIMING.finditer(text) if any(abs(c - m.start()) <= NEAR for c in cards)]


def _python_blocks(source: str) -> list[tuple[int, str]]:
    """(line, text) of every string statement (module, class, function and attribute docstrings) and every run of
    comments on consecutive lines of a Python file."""
    blocks = [
        (node.lineno, node.value.value)
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)
    ]
    run: list[str] = []
    first = last = -1
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type != tokenize.COMMENT:
            continue
        line = tok.start[0]
        if run and line != last + 1:
            blocks.append((first, " ".join(run)))
            run = []
        if not run:
            first = line
        run.append(tok.string.lstrip("#").strip())
        last = line
    if run:
        blocks.append((first, " ".join(run)))
    return blocks


def _comment_blocks(text: str) -> list[tuple[int, str]]:
    """(line, text) of every run of `#` comment lines of a TOML or shell file."""
    blocks: list[tuple[int, str]] = []
    run: list[str] = []
    first = 0
    for i, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith("#"):
            if not run:
                first = i
            run.append(stripped.lstrip("#").strip())
        elif run:
            blocks.append((first, " ".join(run)))
            run = []
    if run:
        blocks.append((first, " ".join(run)))
    return blocks


def _tracked_files() -> list[Path]:
    """The repository's tracked files (git), or every file outside .git and caches where there is no git."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True, timeout=30).stdout
        return [ROOT / name for name in out.decode().split("\0") if name]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "__pycache__", ".pytest_cache", ".ruff_cache", ".state"}
        return [p for p in ROOT.rglob("*") if p.is_file() and not skip.intersection(p.relative_to(ROOT).parts)]


def _docs() -> list[Path]:
    return [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").rglob("*.md"))]


LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
"""An inline markdown link or image: [text](target "title")."""


def _links(markdown: str) -> list[str]:
    """Targets of the inline links of `markdown`, outside fenced code blocks and code spans."""
    text = re.sub(r"^(```|~~~).*?^\1", "", markdown, flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)
    return [m.group(1) for m in LINK.finditer(text)]


def test_card_timing_pattern_flags_measurements_and_spares_units():
    """The rule's detector itself: a timing beside a card name is flagged, a unit's name, a physical duration
    with no card and a card with no timing are not (so the package-wide test below can neither pass vacuously
    nor trip on unit docs)."""
    assert card_timings("P2G 67 µs one particle per thread (H100, Table 2 ficus)") == ["67 µs"]
    assert card_timings("scatter_reduce took 1.9 ms at 183k particles on an H200") == ["1.9 ms"]
    assert card_timings("64 registers on sm_90: K = 16 0.0794 → 0.0782 ms") == ["0.0782 ms"]
    assert card_timings("Δt: time step in s") == []
    assert card_timings("a kick over the first 5 ms, like a hammer blow") == []
    assert card_timings("calibrated against the paper protocol on an H200") == []
    assert card_timings("runs of 8 particles per thread were fastest on Hopper GPUs; see BENCHMARKS.md") == []


def test_package_docstrings_and_comments_quote_no_timing_on_a_named_card():
    """Rule: no docstring or comment under fracture_gs/ (Python files, and the comments of its TOML configs) gives
    a µs or ms timing measured on a named card; such numbers go stale with the next change or card. State the
    reason and point to BENCHMARKS.md (current numbers) or docs/benchmarks/ (the history) instead."""
    found = []
    for path in sorted(PACKAGE.rglob("*")):
        if path.suffix not in (".py", ".toml", ".sh"):
            continue
        text = path.read_text(encoding="utf-8")
        if not (CARD.search(text) and TIMING.search(text)):
            continue  # no block of this file can hold both (and tokenizing every file is slow)
        blocks = _python_blocks(text) if path.suffix == ".py" else _comment_blocks(text)
        rel = path.relative_to(ROOT)
        found += [f"{rel}:{line}: {card_timings(text)}" for line, text in blocks if card_timings(text)]
    assert not found, "timings on a named card in docstrings/comments:\n" + "\n".join(found)


def test_no_tracked_file_points_outside_the_repository():
    """Rule: no tracked file (README.md, BENCHMARKS.md, docs/, code, scripts) names the `shared` folder beside the
    repository by a relative path one level up: a reader of the repository alone cannot follow it."""
    needle = OUTSIDE.encode()
    hits = []
    for path in _tracked_files():
        try:
            data = path.read_bytes()
        except OSError:  # a tracked file deleted in the work tree
            continue
        if needle in data:
            hits.append(str(path.relative_to(ROOT)))
    assert not hits, f"files mentioning {OUTSIDE}: {hits}"


def test_benchmarks_md_holds_only_the_current_numbers():
    """Rule: BENCHMARKS.md has at most 400 lines (one current row per target and a few key tables); the dated
    history belongs in docs/benchmarks/."""
    lines = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= BENCHMARKS_MAX_LINES, f"BENCHMARKS.md has {len(lines)} lines (at most {BENCHMARKS_MAX_LINES})"
    assert lines[0].startswith("# ") and "## Current numbers" in lines, "BENCHMARKS.md must open with its current table"


def test_relative_markdown_links_resolve():
    """Rule: every relative link of README.md, BENCHMARKS.md and docs/**/*.md (anchors aside) names a file or
    folder that exists, relative to the file that holds it."""
    missing = []
    for doc in _docs():
        for target in _links(doc.read_text(encoding="utf-8")):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # a URL (http:, mailto:) or an anchor in the same file
            path = target.split("#", 1)[0].split("?", 1)[0]
            if not (doc.parent / path).exists():
                missing.append(f"{doc.relative_to(ROOT)}: {target}")
    assert not missing, "relative links to files that do not exist:\n" + "\n".join(missing)


def test_link_reader_sees_links_and_skips_code():
    """The link reader behind the rule above: it finds links and images with titles or angle brackets and
    ignores links written inside code spans and fenced blocks (examples, not links)."""
    md = '[a](x.md) ![b](<y.png>) [c](w.md "title")\n`[d](no.md)`\n```\n[e](no2.md)\n```\n[f](#anchor)'
    assert _links(md) == ["x.md", "y.png", "w.md", "#anchor"]
