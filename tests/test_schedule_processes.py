"""render-sim's variants in worker processes on one CPU (`--schedule processes`, `auto`'s choice for long CPU runs).

Warp runs each kernel on one core, so a second core only simulates in a second process. The rule: the same run
in processes is the same run, byte for byte (metrics, topology, PNG frames, the viewer's record), and `auto`
picks processes only where they pay: a CPU, two cores or more, two variants or more, and enough simulation per
variant to pay for a worker's start."""

import hashlib

import pytest
from runutil import assert_same_run, tiny_bread

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.render_sim.job import WORKER_START_WORK, auto_schedule

pytestmark = pytest.mark.usefixtures("one_thread")

LONG = WORKER_START_WORK  # particle-frames just enough to pay for a worker


@pytest.mark.parametrize(
    "device, variants, particles, frames, cores, expected",
    [
        ("cpu", 3, 20_000, 90, 2, "processes"),  # the README's main job
        ("cpu", 2, LONG, 1, 2, "processes"),  # exactly enough work
        ("cpu", 2, LONG - 1, 1, 2, "in_turn"),  # one particle-frame short: a worker would not pay
        ("cpu", 3, 20_000, 90, 1, "in_turn"),  # one core: nothing to run beside
        ("cpu", 1, 20_000, 90, 2, "in_turn"),  # one variant: nothing to run beside
        ("cuda:0", 3, 183_000, 90, 16, "in_turn"),  # a GPU's variants share one card
        ("cuda", 3, 183_000, 90, 16, "in_turn"),
    ],
)
def test_auto_runs_processes_only_where_they_pay(device, variants, particles, frames, cores, expected):
    """`auto`: processes on a CPU with a core to spare, two or more variants and at least WORKER_START_WORK
    particle-frames per variant (a worker's start is paid back); in turn everywhere else."""
    assert auto_schedule(device, variants, particles, frames, cores) == expected


def _digest(folder) -> dict:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.slow
def test_processes_give_the_in_turn_run_byte_for_byte(tmp_path):
    """Three variants in two worker processes on the CPU: every variant's per-frame metrics and the latched
    topology equal the in-turn run's, and so do the PNG frames and the viewer's per-frame record, byte for byte
    (the CPU kernels are deterministic and the workers sum on the parent's thread count). With --profile the
    workers' phases are added to the parent's: every frame of every variant is counted once."""
    variants = ["stress_zero", "full", "baseline"]
    cfg = tiny_bread(10)
    runner.run_render_sim(cfg, variants, "cpu", tmp_path / "turn", schedule="in_turn")
    summary = runner.run_render_sim(
        tiny_bread(10), variants, "cpu", tmp_path / "procs", schedule="processes", profile=True
    )
    assert_same_run(tmp_path / "turn", tmp_path / "procs", variants)
    assert _digest(tmp_path / "turn" / "frames") == _digest(tmp_path / "procs" / "frames")
    assert _digest(tmp_path / "turn" / "view") == _digest(tmp_path / "procs" / "view")
    simulate = next(line for line in summary.profile.splitlines() if line.startswith("| simulate |"))
    assert simulate.split("|")[-2].strip() == str(len(variants) * cfg.frames), simulate


def test_processes_refuse_a_single_variant(capsys):
    """`--schedule processes` with one variant would start a worker for nothing: one sentence, exit 2."""
    assert cli.main(["render-sim", "bread", "--variants", "full", "--schedule", "processes"]) == 2
    err = capsys.readouterr().err
    assert "--schedule processes" in err and "one variant" in err and err.count("\n") == 1


def test_workers_sharing_a_cpu_split_kernels_over_their_share_only(monkeypatch):
    """Per-particle kernels split into ranges over this process's cores (`runtime.cpu_ranges`); a worker that
    shares the CPU with others gets its share (`share_cpu`), so two workers on two cores run one range each
    instead of four threads fighting for two cores; the share is restored afterwards."""
    from fracture_gs import runtime

    monkeypatch.setattr(runtime, "usable_cores", lambda: 4)  # a 4-core machine
    assert len(runtime.cpu_ranges(100_000)) == 4  # every core by default
    before = runtime.share_cpu(2)
    try:
        ranges = runtime.cpu_ranges(100_000)
        assert len(ranges) == 2 and ranges[0][0] == 0 and ranges[-1][1] == 100_000
        runtime.share_cpu(1)
        assert runtime.cpu_ranges(100_000) == [(0, 100_000)]
    finally:
        assert runtime.share_cpu(before) == 1
    assert len(runtime.cpu_ranges(100_000)) == 4


def test_range_views_are_the_arrays_for_the_whole_range_and_slices_otherwise():
    """A kernel over the particles [a, b) reads the arrays' [a, b) views; for every particle, the arrays
    themselves (no new slice objects per launch). Either way the views hold exactly the range's elements."""
    import torch
    import warp as wp

    from fracture_gs.runtime import ensure_warp, range_views

    ensure_warp()
    x = wp.from_torch(torch.arange(30, dtype=torch.float32).reshape(10, 3), dtype=wp.vec3)
    m = wp.from_torch(torch.arange(10, dtype=torch.int32))
    whole = range_views([x, m], 0, 10)
    assert whole[0] is x and whole[1] is m
    part = range_views([x, m], 3, 7)
    assert part[0].shape == (4,) and part[1].shape == (4,)
    assert wp.to_torch(part[1]).tolist() == [3, 4, 5, 6]
    assert wp.to_torch(part[0])[0].tolist() == [9.0, 10.0, 11.0]
    head = range_views([x, m], 0, 5)  # from 0 but not to the end: still a slice
    assert head[0] is not x and head[0].shape == (5,)
