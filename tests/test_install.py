"""A non-editable install works outside the checkout: `pip install .` (here `--target`, without
dependencies, which this venv already has) puts everything `fracture-gs bench` and `fracture-gs
figures` need into the installed package — the experiment configs, the paper code — and neither
reaches back into the repository (no `examples/` or `benchmarks/`, no sys.path edits)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    target = tmp_path_factory.mktemp("site")
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "--no-compile",
            "--target",
            str(target),
            str(ROOT),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    work = tmp_path_factory.mktemp("elsewhere")  # not the checkout: nothing is importable from the cwd
    env = {**os.environ, "PYTHONPATH": str(target), "FRACTURE_GS_DEBUG": "1"}
    return target, work, env


def run(installed, *args, timeout=900):
    target, work, env = installed
    return subprocess.run(
        [sys.executable, "-m", "fracture_gs.cli", *args],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.slow
def test_installed_package_is_the_one_imported(installed):
    target, work, env = installed
    out = subprocess.run(
        [sys.executable, "-c", "import fracture_gs, fracture_gs.paper.figures as f; print(f.__file__)"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert Path(out.stdout.strip()).is_relative_to(target)
    assert not (target / "examples").exists() and not (target / "benchmarks").exists()


@pytest.mark.slow
def test_installed_bench_writes_table2(installed):
    out = run(
        installed,
        "bench",
        "--device",
        "cpu",
        "--particles",
        "1500",
        "--steps",
        "2",
        "--warmup",
        "1",
        "--trials",
        "1",
        "--out",
        "bench",
    )
    assert out.returncode == 0, out.stderr[-3000:]
    md = (installed[1] / "bench" / "bench.md").read_text()
    assert "| FractureFields | 1/1/0 |" in md and "| Shared Field | 1/1/0 |" in md


@pytest.mark.slow
def test_installed_figures_writes_a_measured_table2(installed):
    """The failure this guards against: Table 2 silently 'pending' because the benchmark lived outside the package."""
    out = run(installed, "figures", "--device", "cpu", "--only", "bench", "--out", "figs")
    assert out.returncode == 0, out.stderr[-3000:]
    table = (installed[1] / "figs" / "tables" / "table2_efficiency.md").read_text()
    assert "pending" not in table
    assert "FractureFields" in table and "(CPU)" in table
    assert (installed[1] / "figs" / "README.md").exists()


@pytest.mark.slow
def test_installed_sweep_finds_its_builtin_specs(installed):
    """The sweep specs ship as package data: `fracture-gs sweep accuracy_full --list` from the installed
    package lists the 30 cells of the full speed-against-error sweep, and `accuracy` its 18."""
    for name, cells in (("accuracy_full", 30), ("accuracy", 18)):
        out = run(installed, "sweep", name, "--list", "--device", "cpu", "--out", "sweep_out", timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        rows = [line for line in out.stdout.splitlines() if "accuracy  pending" in line]
        assert len(rows) == cells, out.stdout[-2000:]
