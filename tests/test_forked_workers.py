"""Worker processes forked at a CPU run's start (`render_sim.forked`, the processes schedule).

A forked worker skips the seconds a spawned one spends importing torch and Warp again, so on a CPU each variant
gets its own process (`job.cpu_slots`). A fork is only safe before the parent's OpenMP threads exist: each child
proves OpenMP works in it before the parent counts on it, and a child that does not answer in time makes the run
spawn fresh workers instead of hanging.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from runutil import metrics_rows

from fracture_gs.render_sim import forked
from fracture_gs.render_sim.job import cpu_slots


@pytest.mark.parametrize(
    "variants, cores, forked_, expected",
    [
        (3, 2, True, 3),  # the README's main job: each variant its own process, 1.5 variants' time on 2 cores
        (3, 2, False, 2),  # spawned workers import torch again: one per core
        (5, 2, True, 4),  # at most two per core
        (2, 16, True, 2),  # never more than the variants
        (1, 4, True, 1),
        (3, 1, False, 1),
    ],
)
def test_cpu_slots_give_forked_workers_one_variant_each_up_to_two_per_core(variants, cores, forked_, expected):
    """Processes for a CPU run's variants: forked ones (free to start) one per variant up to two per core; spawned
    ones (an import each) one per core; never more than the variants and at least the caller."""
    assert cpu_slots(variants, cores, forked_) == expected


def _never_ready(
    jobs, ready, stop, results, device, gsplat
):  # a child whose fork broke OpenMP: it takes its job and hangs
    jobs.get()
    time.sleep(60)


def test_a_child_that_does_not_prove_openmp_in_time_is_stopped(monkeypatch):
    """A forked child that does not report within READY_SECONDS (a broken OpenMP after the fork hangs it) makes
    `start` give up: it returns None, so the caller spawns workers, and no child is left running."""
    monkeypatch.setattr(forked, "_child", _never_ready)
    monkeypatch.setattr(forked, "READY_SECONDS", 0.5)
    workers = forked.ForkedWorkers(2)
    t0 = time.perf_counter()
    assert workers.start(print, [(1, 1, (), {})]) is None
    assert time.perf_counter() - t0 < 10
    assert not any(p.is_alive() for p in workers.procs)


def test_children_without_a_job_end_at_once():
    """A run that does not take the processes schedule (`auto` chose in turn) ends its forked children: `close`
    leaves none running."""
    workers = forked.ForkedWorkers(2)
    workers.close()
    assert not any(p.is_alive() for p in workers.procs)
    assert all(p.exitcode == 0 for p in workers.procs)


def test_a_healthy_child_reports_ready_with_the_parents_thread_count():
    """Forked before any parallel torch op (a fresh interpreter), a child runs a parallel reduction on the
    parent's thread count and reports in time: `start` returns the child."""
    code = (
        "import torch\n"
        "from fracture_gs.render_sim import forked\n"
        "def probe(jobs, ready, stop, results, device, gsplat, parent):  # the real child's first steps\n"
        "    fn, slot, threads, args, kwargs = jobs.get()\n"
        "    torch.set_num_threads(threads)\n"
        "    torch.ones(1 << 16, dtype=torch.float64).sum()\n"
        "    ready.put((slot, None))\n"
        "    results.put(('threads', torch.get_num_threads()))\n"
        "forked._child = probe\n"
        "w = forked.ForkedWorkers(1)\n"
        "procs = w.start(print, [(1, 2, (), {})])\n"
        "print(procs is not None, w.results.get(timeout=10))\n"
        "for p in procs or []: p.join(10)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[-2] == "True ('threads', 2)"


@pytest.mark.slow
def test_the_cli_forks_its_workers_and_gives_the_in_turn_run(tmp_path, device):
    """`fracture-gs render-sim` with the processes schedule on the tests' device (the CPU here, `--device cuda` on a
    GPU machine, where the fork must come before anything starts CUDA) forks one worker per variant beyond the
    first (it says so) and never falls back to spawning; every variant writes every frame's row and latches at the
    leader's frame. On the CPU the metrics are the same run in turn's, byte for byte (a GPU's atomics are not)."""
    base = [sys.executable, "-m", "fracture_gs.cli", "render-sim", "bread", "--device", device, "--frames", "12"]
    base += ["--particles", "2500", "--resolution", "64x48", "--no-view-record"]
    runs = {}
    for schedule in ("processes", "in-turn") if device == "cpu" else ("processes",):
        out = subprocess.run(
            base + ["--schedule", schedule, "--out", str(tmp_path / schedule)], capture_output=True, text=True
        )
        assert out.returncode == 0, out.stderr[-2000:]
        runs[schedule] = out.stdout + out.stderr
    assert "3 variants in 3 processes (forked at the start)" in runs["processes"]
    assert "spawning" not in runs["processes"]
    rows = [json.loads(line) for line in (tmp_path / "processes" / "metrics.jsonl").read_text().splitlines()]
    assert sorted((r["variant"], r["frame"]) for r in rows) == sorted(
        (v, f) for v in ("baseline", "stress_zero", "full") for f in range(13)
    )
    latches = [json.loads((tmp_path / s / "summary.json").read_text())["variants"] for s in runs]
    assert len({json.dumps(v["latch"]) for v in latches[0]}) == 1 and latches[0][0]["latch"] is not None
    if device == "cpu":
        assert metrics_rows(tmp_path / "processes") == metrics_rows(tmp_path / "in-turn")
        assert [v["latch"] for v in latches[0]] == [v["latch"] for v in latches[1]]


@pytest.mark.slow
def test_ctrl_c_stops_every_forked_worker_and_keeps_the_partial_run(tmp_path):
    """A terminal's Ctrl-C (SIGINT to the whole process group) during a processes run: the command exits 130
    within seconds, says where the partial outputs are, keeps the frames' metrics and the summary written so far,
    and leaves no worker process behind."""
    import os
    import signal

    out = tmp_path / "run"
    argv = [sys.executable, "-m", "fracture_gs.cli", "render-sim", "bread", "--device", "cpu", "--frames", "400"]
    argv += ["--particles", "2500", "--resolution", "64x48", "--schedule", "processes", "--out", str(out)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    part = out / ".metrics_full.jsonl"  # a forked follower's rows, written as it goes
    while time.monotonic() < deadline and not (part.exists() and part.read_text().count("\n") >= 3):
        assert proc.poll() is None, proc.communicate()[0][-2000:]
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    t0 = time.monotonic()
    text = proc.communicate(timeout=60)[0]
    assert proc.returncode == 130, text[-2000:]
    assert time.monotonic() - t0 < 30
    assert f"partial outputs are in {out}" in text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] and {v["variant"] for v in summary["variants"]} == {"baseline", "stress_zero", "full"}
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert {r["variant"] for r in rows} == {"baseline", "stress_zero", "full"} and len(rows) < 3 * 401
    left = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True).stdout.split()
    assert left == [], left


def test_a_child_whose_parent_dies_before_its_job_exits():
    """A run killed outright (SIGKILL, out of memory) while it prepares the scene sends no job: its forked children
    notice their parent is gone and exit within seconds instead of waiting forever."""
    code = (
        "import os, signal, sys\n"
        "from fracture_gs.render_sim import forked\n"
        "w = forked.ForkedWorkers(2)\n"
        "print(' '.join(str(p.pid) for p in w.procs), flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    pids = [int(p) for p in out.stdout.split()]
    assert len(pids) == 2, out.stderr[-2000:]
    deadline = time.monotonic() + 15
    alive = pids
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = [p for p in pids if _running(p)]
    assert alive == [], alive


def test_a_child_that_starts_after_its_parent_died_exits():
    """The parent's pid travels with the fork: a child that reaches its loop only after the parent was killed (it is
    the init process's child by then) still sees its parent gone and exits, instead of waiting forever (the test
    above hung for two minutes under a loaded suite when the children started late)."""
    code = (
        "import os, signal, time\n"
        "from fracture_gs.render_sim import forked\n"
        "run = forked._child\n"
        "def late(*args, **kwargs):\n"
        "    time.sleep(1.0)  # the parent is killed meanwhile\n"
        "    run(*args, **kwargs)\n"
        "forked._child = late\n"
        "w = forked.ForkedWorkers(2)\n"
        "print(' '.join(str(p.pid) for p in w.procs), flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    pids = [int(p) for p in proc.stdout.readline().split()]
    proc.wait(60)
    assert len(pids) == 2
    deadline = time.monotonic() + 20
    alive = pids
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = [p for p in pids if _running(p)]
    for p in alive:  # a failure leaves no orphan behind
        os.kill(p, signal.SIGKILL)
    assert alive == [], alive


def _running(pid: int) -> bool:  # a live process, not a zombie waiting for a parent that is gone
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
