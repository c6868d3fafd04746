"""Every script under benchmarks/ runs: each is started as a user would (a subprocess from the checkout) in its
small CPU mode, and what it prints or writes is checked, so an example cannot rot silently."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"


def _run(args: list[str], cwd: Path, timeout: int = 600) -> str:
    proc = subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.slow
def test_soak_holds_no_memory_and_repeats_its_metrics(tmp_path):
    """benchmarks/soak.py: two render-sim + bench runs on the CPU give identical metrics (the simulation is
    deterministic on one device) and the loop's summary says so."""
    out = tmp_path / "soak"
    _run(
        [str(BENCH / "soak.py"), "--device", "cpu", "--iterations", "2", "--frames", "2"]
        + ["--particles", "1500", "--bench-particles", "2000", "--out", str(out)],
        tmp_path,
    )
    summary = json.loads((out / "soak.json").read_text())["summary"]
    assert summary["runs"] == 2 and summary["all_same_metrics"] and summary["max_held_bytes"] == 0


@pytest.mark.slow
def test_bench_fragments_smoke(tmp_path):
    """benchmarks/bench_fragments.py: the K-fragment Table 2 on a tiny ficus prints a row per K and grid storage,
    with positive times; no multi-fragment node overflows its slots at K ≤ 4 and no stencil left its box."""
    text = _run(
        [str(BENCH / "bench_fragments.py"), "--device", "cpu", "--particles", "2000", "--n", "24", "--K", "2,4"]
        + ["--steps", "3", "--warmup", "1", "--trials", "1", "--placements", "1"],
        tmp_path,
    )
    rows = [line.split("|") for line in text.splitlines() if line.startswith("| 2 |") or line.startswith("| 4 |")]
    assert [r[3].strip() for r in rows] == ["slots", "boxes"] * 2, text
    assert all(float(r[4]) > 0 and float(r[6]) > 0 and r[-3].strip() == "0" and r[-2].strip() == "0" for r in rows), (
        text
    )


def test_bench_fragments_times_every_branch_in_each_trial():
    """benchmarks/bench_fragments.py's timing loop visits every build once per trial, in turn (Shared, then
    FractureFields, then Shared again), so a host that drifts during the run shifts both branches alike: the
    ratio is not the drift between two blocks timed minutes apart."""
    import contextlib
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_fragments", BENCH / "bench_fragments.py")
    bf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bf)
    calls = []

    class Build:
        device = "cpu"

        def __init__(self, name):
            self.name = name

        def _stream_scope(self):
            return contextlib.nullcontext()

        def transfer(self):
            calls.append(self.name)

    samples = bf.time_builds([Build("shared"), Build("boxes")], steps=2, warmup=1, trials=2)
    assert calls == ["shared", "boxes"] + ["shared"] * 2 + ["boxes"] * 2 + ["shared"] * 2 + ["boxes"] * 2
    assert [len(s) for s in samples] == [2, 2]


@pytest.mark.slow
def test_bench_diff_smoke(tmp_path):
    """benchmarks/bench_diff.py: forward and backward of a substep both run and report positive times."""
    text = _run(
        [str(BENCH / "bench_diff.py"), "--device", "cpu", "--particles", "1000", "--substeps", "2"]
        + ["--repeats", "1"],
        tmp_path,
    )
    report = json.loads(text[text.index("{") :])
    assert report["forward_ms_per_substep"] > 0 and report["backward_ms_per_substep"] > 0, report


@pytest.mark.slow
def test_check_render_gpu_cpu_dry_run(tmp_path):
    """benchmarks/check_render_gpu.py --cpu-dry-run: the cross-check's own bookkeeping passes on the CPU."""
    assert "OK" in _run(
        [str(BENCH / "check_render_gpu.py"), "--cpu-dry-run", "--repeats", "1", "--no-assets"], tmp_path
    )


@pytest.mark.slow
def test_fragment_boxes_counts_nodes_as_by_hand(tmp_path):
    """benchmarks/fragment_boxes.py: two particles of fragment 0 whose stencils share one node and a particle of
    fragment 1 on the second one's stencil: boxes of 5³ and 3³ nodes, 53 and 27 nodes reached, the 27 of
    fragment 1 all shared with fragment 0; the script's table runs on a tiny ficus."""
    import importlib.util

    import torch

    spec = importlib.util.spec_from_file_location("fragment_boxes", BENCH / "fragment_boxes.py")
    boxes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(boxes)
    dx = 1.0 / 8
    x = torch.tensor([[2.6, 2.6, 2.6], [4.6, 4.6, 4.6], [4.6, 4.6, 4.6]]) * dx  # stencil bases 2, 4, 4
    got = boxes.geometry(x, torch.tensor([0, 0, 1]), dx, 8)
    assert got == {
        "fragments": 2,
        "shared_box_nodes": 125,
        "shared_reached_nodes": 53,
        "fragment_box_nodes": 125 + 27,
        "fragment_reached_nodes": 53 + 27,
        "nodes_of_two_or_more": 27,
        "grid_nodes": 512,
    }
    rows = json.loads(
        _run([str(BENCH / "fragment_boxes.py"), "--particles", "3000", "--n", "32", "--K", "2,8", "--json"], tmp_path)
    )
    assert [r["K"] for r in rows] == [2, 8] and all(r["fragment_box_nodes"] > 0 for r in rows)
    assert rows[1]["nodes_of_two_or_more"] > rows[0]["nodes_of_two_or_more"], "more pieces, more faces"


@pytest.mark.slow
def test_capture_targets_reads_back_what_a_user_gets(tmp_path):
    """benchmarks/capture_targets.py on a 5,000-Gaussian real .splat subset, 4 frames of a drop: the run is timed
    from the shell and its row reads the pieces, separation and edge strength back from the run's own outputs (a 4-frame
    drop breaks nothing, so the targets are reported as missed and the script exits 1)."""
    capture = BENCH.parent / "tests" / "data" / "captures" / "luma_seal_5k.splat"
    out = tmp_path / "targets"
    cmd = [sys.executable, str(BENCH / "capture_targets.py"), str(capture), "--loads", "drop", "--frames", "4"]
    proc = subprocess.run([*cmd, "--out", str(out)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    row = json.loads(next(line for line in proc.stdout.splitlines() if line.startswith("{")))
    assert row["rc"] == 0 and row["wall_s"] > 0 and row["load"] == "drop" and row["ok"] is False
    assert row["pieces"] == 0 and 0.5 < row["edge"] < 1.5, row
    assert "| luma_seal_5k.splat | drop |" in (out / "targets.md").read_text()


@pytest.mark.slow
def test_surface_measure_times_both_and_they_agree(tmp_path):
    """benchmarks/surface_measure.py: on three small pressed blocks the Warp measure and its torch twin each print a
    positive time, the same count of particles behind another piece and the same deepest depth (about the two
    spacings the blocks were pressed by)."""
    text = _run([str(BENCH / "surface_measure.py"), "--device", "cpu", "--cells", "10", "--repeats", "1"], BENCH.parent)
    rows = [line for line in text.splitlines() if " ms a call, " in line]
    assert [r.split(":")[0] for r in rows] == ["Warp", "torch twin"], text
    ms = [float(r.split(": ")[1].split(" ms")[0]) for r in rows]
    behind = [r.split("particles, ")[1].split(" behind")[0] for r in rows]
    deepest = [float(r.split("deepest ")[1].split(" spacings")[0]) for r in rows]
    assert min(ms) > 0 and behind[0] == behind[1] and int(behind[0]) > 0, text
    assert deepest[0] == pytest.approx(deepest[1], abs=1e-3) and 0.5 < deepest[0] < 3.0, text


@pytest.mark.slow
def test_frame_costs_counts_each_part_of_a_frame(tmp_path):
    """benchmarks/frame_costs.py: a tiny bread run prints one row per part of a frame after the latch, with the
    diagnostics' torch ops counted (the surface measure among them, in Warp: far fewer ops than its twin's ≈ 900)."""
    text = _run(
        [str(BENCH / "frame_costs.py"), "--device", "cpu", "--particles", "3000", "--frames", "16"], BENCH.parent
    )
    rows = {r.split("|")[1].strip(): r.split("|") for r in text.splitlines() if r.startswith("| ") and "---" not in r}
    assert {"paint (draw + host copy)", "view record write", "diagnostics: surface penetration"} <= set(rows), text
    ops = int(rows["diagnostics: surface penetration"][5])
    assert 0 < ops < 600, text


def test_metrics_gap_reports_the_largest_difference_per_metric(tmp_path):
    """benchmarks/metrics_gap.py: rows are matched by variant and frame (not by order), each metric's largest
    |a − b| is printed, momentum by its summed absolute components, and rows one run lacks are left out."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    rows_a = [
        {"variant": "full", "frame": 1, "opening": 1.0, "momentum": [1.0, -2.0, 0.0]},
        {"variant": "full", "frame": 2, "opening": 2.0, "momentum": [0.0, 0.0, 0.0]},
        {"variant": "baseline", "frame": 1, "opening": 5.0},
    ]
    rows_b = [  # other order, one row fewer
        {"variant": "full", "frame": 2, "opening": 2.5, "momentum": [0.0, 0.0, 1.0]},
        {"variant": "full", "frame": 1, "opening": 1.25, "momentum": [1.0, 2.0, 0.5]},
    ]
    (a / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows_a))
    (b / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows_b))
    out = _run([str(BENCH / "metrics_gap.py"), str(a), str(b)], tmp_path)
    assert out.strip() == f"{a} against {b}: {{'momentum': '1', 'opening': '0.5'}}"


def test_same_outputs_ignores_timings_only(tmp_path):
    """benchmarks/same_outputs.py: two run folders that differ only in wall-clock fields (summary.json's wall_s,
    substeps_per_s, profile, out_dir; summary.md's last column; profile.md) are the same run; a changed byte in any
    other file, a changed number in summary.json or summary.md, or a file only one holds is a difference (exit 1)."""

    def run_folder(name: str, wall: float, opening: float, png: bytes) -> Path:
        d = tmp_path / name
        (d / "frames").mkdir(parents=True)
        (d / "frames" / "compare_0000.png").write_bytes(png)
        (d / "metrics.jsonl").write_text('{"frame": 0}\n')
        summary = {"out_dir": str(d), "variants": [{"variant": "full", "wall_s": wall, "opening": opening}]}
        (d / "summary.json").write_text(json.dumps(summary))
        (d / "summary.md").write_text(f"| variant | opening | substeps/s |\n| full | {opening} | {100 / wall:.1f} |\n")
        (d / "profile.md").write_text(f"wall time {wall} s\n")
        return d

    a = run_folder("a", 2.0, 1.5, b"\x89PNG0")
    b = run_folder("b", 3.0, 1.5, b"\x89PNG0")
    out = _run([str(BENCH / "same_outputs.py"), str(a), str(b)], tmp_path)
    assert out.strip() == "identical: 5 files"

    def differs(c: Path) -> str:
        proc = subprocess.run(
            [sys.executable, str(BENCH / "same_outputs.py"), str(a), str(c)], capture_output=True, text=True
        )
        assert proc.returncode == 1, proc.stdout + proc.stderr
        return proc.stdout

    assert differs(run_folder("c", 2.0, 1.5, b"\x89PNG1")).strip() == "frames/compare_0000.png differs"
    found = differs(run_folder("d", 2.0, 1.75, b"\x89PNG0")).splitlines()
    assert found == ["summary.json differs beyond its timings", "summary.md differs beyond its substeps/s column"]
    e = run_folder("e", 2.0, 1.5, b"\x89PNG0")
    (e / "frames" / "compare_0001.png").write_bytes(b"x")
    assert differs(e).strip() == f"only in {e}: frames/compare_0001.png"


def test_spy_summary_counts_each_function_once_per_stack(tmp_path):
    """benchmarks/spy_summary.py: a py-spy raw file summed per thread; a function twice in one stack (recursion) counts
    once inclusive; the self frame is the innermost frame matching --only, `(outside)` when none does; seconds are
    samples over the rate."""
    raw = tmp_path / "raw.txt"
    raw.write_text(
        "thread (11): MainThread;main (fracture_gs/cli/__init__.py:3);f (fracture_gs/a.py:1);f (fracture_gs/a.py:2);"
        "get (queue.py:9) 30\n"
        "thread (11): MainThread;main (fracture_gs/cli/__init__.py:3);g (fracture_gs/b.py:5) 10\n"
        "thread (12): fgs-render;_bootstrap (threading.py:1) 4\n"
    )
    out = _run([str(BENCH / "spy_summary.py"), str(raw), "--rate", "10", "--only", "fracture_gs"], tmp_path)
    main_part, render_part = out.split("## fgs-render")[0], out.split("## fgs-render")[1]
    assert "## MainThread: 40 samples = 4.00 s" in main_part
    assert "| main (fracture_gs/cli/__init__.py) | 40 | 4.00 |" in main_part
    assert "| f (fracture_gs/a.py) | 30 | 3.00 |" in main_part  # once per stack, though twice in it
    assert "| get (queue.py) |" not in main_part  # outside --only
    assert ": 4 samples = 0.40 s" in render_part and "| (outside) | 4 | 0.40 |" in render_part


def test_gpu_busy_without_cuda_says_so(tmp_path):
    """benchmarks/gpu_busy.py where torch sees no CUDA device (hidden on a GPU machine): one sentence and exit
    status 2, no profiler traceback."""
    import os

    env = {**os.environ, "CUDA_VISIBLE_DEVICES": ""}
    proc = subprocess.run(
        [sys.executable, str(BENCH / "gpu_busy.py"), "--", "validate", "bread"], capture_output=True, text=True, env=env
    )
    assert proc.returncode == 2 and "sees no CUDA device" in proc.stderr and "Traceback" not in proc.stderr


def test_gpu_busy_union_counts_overlaps_once():
    """benchmarks/gpu_busy.py's device busy time: the union of the intervals, overlaps and nesting counted once."""
    sys.path.insert(0, str(BENCH))
    try:
        from gpu_busy import busy_union
    finally:
        sys.path.remove(str(BENCH))
    assert busy_union([]) == 0.0
    assert busy_union([(5.0, 6.0), (0.0, 2.0), (1.0, 3.0), (5.5, 5.7)]) == 4.0
    assert busy_union([(0.0, 10.0), (2.0, 3.0), (9.0, 11.0)]) == 11.0


@pytest.mark.slow
def test_overlap_probe_times_each_mode_and_changes_no_number(tmp_path):
    """benchmarks/overlap_probe.py: every mode runs in a process of its own and gets a row of the table; a mode
    changes how the run executes, never what it computes: with nothing drawn anew (norender) and without the surface
    measure (nosurface; these frames have no piece behind another) the metrics are the shipped run's, while the
    norender frames after the first are not the shipped ones (its painter hands back the first image)."""
    job = "recontact --frames 3 --particles 2000 --variants full --resolution 160x120"
    args = [str(BENCH / "overlap_probe.py"), "--device", "cpu", "--job", job, "--rounds", "1"]
    out = _run([*args, "--out-root", str(tmp_path), "base", "norender", "nosurface"], BENCH.parent)
    rows = {r.split("|")[1].strip(): r for r in out.splitlines() if r.startswith("| ") and "---" not in r}
    assert {"base", "norender", "nosurface"} <= set(rows), out
    assert all(float(rows[m].split("|")[2]) > 0 for m in ("base", "norender", "nosurface")), out

    def metrics(mode: str) -> list:
        lines = (tmp_path / f"probe_{mode}" / "metrics.jsonl").read_text().splitlines()
        return [{k: v for k, v in json.loads(line).items() if k != "wall_s"} for line in lines]

    shipped = metrics("base")
    assert any(r.get("latched") for r in shipped) and all(r.get("fragment_penetration", 0) == 0 for r in shipped)
    assert metrics("norender") == shipped and metrics("nosurface") == shipped

    def frame(mode: str, i: int) -> bytes:
        return (tmp_path / f"probe_{mode}" / "frames" / f"compare_{i:04d}.png").read_bytes()

    assert frame("norender", 0) == frame("base", 0) and frame("norender", 3) != frame("base", 3)
