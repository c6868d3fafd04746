"""CI runs what the README tells a developer to run: `.ci/run` executes exactly README's test command (the second
line of its first code block), and that command installs everything the suite needs on a fresh machine: the
browser the viewer's tests drive (Debian's chromium, and xvfb for its CPU-side GL), the viewer (the `view`
extra: viser) and playwright (the `dev` extra)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    block = re.search(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert block, "README.md opens with a bash block of its two lead commands"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_ci_runs_exactly_the_readme_test_command():
    """The last command of .ci/run is README's second lead command, character for character."""
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line and not line.startswith("#")]
    setup = ["set -euo pipefail", 'cd "$(dirname "$0")/.."']
    assert ci[:-1] == setup, ci
    assert ci[-1] == readme_commands()[1]


def test_the_test_command_installs_what_the_suite_needs():
    """The test command installs chromium and xvfb when missing, then the `dev` and `view` extras, which hold
    playwright and viser."""
    test = readme_commands()[1]
    assert "command -v chromium" in test and "apt-get install -y -qq chromium xvfb" in test
    assert test.index("apt-get install") < test.index("pytest")
    assert '-e ".[dev,view]"' in test
    pyproject = (ROOT / "pyproject.toml").read_text()
    dev = re.search(r"^dev = \[(.*?)^\]", pyproject, re.S | re.M)
    assert dev and '"playwright>=' in dev.group(1)
    assert re.search(r'^view = \["viser>=1\.1,<1\.2"\]$', pyproject, re.M)
