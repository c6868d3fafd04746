"""`fracture-gs sweep`: spec checks, cell expansion, the cache, failures, devices, launches, and two gloo
ranks on the CPU giving exactly the rows of one process.

The multi-process tests start real processes (torchrun for the equality test, two hand-launched ranks
for the dead-rank test) on 127.0.0.1 with a free port. Cells are tiny (a few hundred particles, well
under a second each), so the file takes well under two minutes on two CPU cores once Warp's kernels
are cached.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

from fracture_gs.cli.sweep import main as sweep_main
from fracture_gs.errors import ConfigError
from fracture_gs.sweep import SPEC_DIR, driver, expand, load_spec
from fracture_gs.sweep import distributed as D
from fracture_gs.sweep.cells import WALL_KEYS

REPO = Path(__file__).resolve().parent.parent
TIMEOUT = 240

TINY = """\
[sweep]
title = "tiny"
warmup = false

[[accuracy]]
label = "dx"
case = ["bar", "spin"]
cells = [16, 24]
cfl = 0.8

[[scene]]
config = "recontact"
variant = ["local_multifield", "full"]
particles = 300
frames = 3
cells = 32
"""
# four accuracy cells and two scene cells, each well under a second on one CPU core

NOT_METRICS = WALL_KEYS | driver.RUN_KEYS  # wall times, and where/when a cell ran


def write(tmp: Path, text: str, name: str = "spec.toml") -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def metrics(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in NOT_METRICS} for r in rows]


def rows_of(out: Path) -> list[dict]:
    return json.loads((out / "sweep.json").read_text())["rows"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def child_env(**extra) -> dict:
    """Environment of a launched rank: this checkout first on the path, no stray torchrun variables."""
    env = {k: v for k, v in os.environ.items() if k not in ("RANK", "WORLD_SIZE", "LOCAL_RANK", "LOCAL_WORLD_SIZE")}
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("FRACTURE_GS_DEBUG", None)
    if sys.platform.startswith("linux") and Path("/sys/class/net/lo").exists():
        env.setdefault("GLOO_SOCKET_IFNAME", "lo")  # gloo needs an interface when the hostname does not resolve
    return {**env, **extra}


def launcher(tmp: Path) -> Path:
    """A script that runs the sweep subcommand (wired into `fracture-gs` or not, it is the same code)."""
    return write(tmp, "import sys\nfrom fracture_gs.cli.sweep import main\nsys.exit(main(sys.argv[1:]))\n", "run.py")


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    """The tiny sweep run once by one process, in this process: (spec path, output folder, exit code)."""
    tmp = tmp_path_factory.mktemp("single")
    spec = write(tmp, TINY)
    code = sweep_main([str(spec), "--device", "cpu", "--out", str(tmp / "out")])
    return spec, tmp / "out", code


# ---------------------------------------------------------------- the spec


BAD_SPECS = [
    ("[[acuracy]]\n", "acuracy", "did you mean 'accuracy'"),
    ('[[accuracy]]\ncase = "bars"\ncells = 16\ncfl = 0.4\n', "accuracy[0].case", "'bars'"),
    ('[[accuracy]]\ncase = "bar"\ncells = 16\ncfl = 1.5\n', "accuracy[0].cfl", "1.5"),
    ('[[accuracy]]\ncase = "bar"\ncells = [16, 18]\ncfl = 0.4\n', "accuracy[0].cells", "18"),
    ('[[accuracy]]\ncase = "spin"\ncells = 16\n', "accuracy[0].cfl is missing", "cfl = [0.4]"),
    ('[sweep]\nwarmup = "yes"\n', "sweep.warmup", "'yes'"),
    ("[sweep]\n", "defines no cells", "[[accuracy]]"),
    ('[[scene]]\nconfig = "recontact"\nvariant = ["full", "full"]\n', "scene[0].variant", "'full' twice"),
    ('[[scene]]\nconfig = "recontact"\n[scene.material]\nnu = [0.3, 0.6]\n', "material.nu = 0.6", "nu = 0.3"),
    ('[[scene]]\nconfig = "recontact"\n[scene.material]\nEE = [1.0]\n', "scene[0].material.EE", "did you mean 'E'"),
    ('[[scene]]\nconfig = "recontact"\n[scene.set]\n"material_map.5.E" = [1.0]\n', "material_map.5", "index"),
    ('[[scene]]\nconfig = "no_such_config"\n', "scene[0].config", "'no_such_config'"),
    ('[[scene]]\nconfig = "recontact"\nvariant = "baseline"\nseed = 1\nrender = true\n', "scene[0].seed", "seed = 0"),
    ("x = [\n", "invalid TOML", "fix the syntax"),
]


@pytest.mark.parametrize("text, key, fix", BAD_SPECS, ids=[b[1] for b in BAD_SPECS])
def test_bad_spec_is_one_sentence_naming_file_key_and_fix(tmp_path, text, key, fix):
    """Every spec problem, from a typo'd table to a material value the scene config rejects, is a
    ConfigError whose message is one line that starts with the spec file and names the key and a fix."""
    path = write(tmp_path, text, "bad_spec.toml")
    with pytest.raises(ConfigError) as info:
        expand(load_spec(path))
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}: "), msg
    assert key in msg and fix in msg, msg
    assert msg.endswith((".", "?")), msg


def test_bad_spec_through_the_cli_is_one_line_and_exit_2(tmp_path, capsys):
    """The command line turns a spec error into `fracture-gs: error: <sentence>` and exit code 2, with
    no traceback, before it creates the output folder."""
    path = write(tmp_path, '[[accuracy]]\ncase = "bar"\ncells = 16\ncfl = 0\n')
    assert sweep_main([str(path), "--out", str(tmp_path / "never")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith("fracture-gs: error: ") and "accuracy[0].cfl" in err[0], err
    assert not (tmp_path / "never").exists()


def test_builtin_accuracy_spec_is_the_quick_bench_sweep():
    """configs/sweeps/accuracy.toml expands to exactly the settings `bench --accuracy --quick` runs
    (fracture_gs.paper.accuracy.SWEEPS["quick"]: its Δx sweeps at the fixed CFL, its Δt sweeps at the
    fixed Δx, the shared setting once), in the same case order."""
    from fracture_gs.paper.accuracy import SWEEPS

    cells = expand(load_spec("accuracy"))
    want = []
    for case, (dxs, cfl0, dx0, cfls) in SWEEPS["quick"].items():
        for setting in [(case, round(1 / dx), cfl0) for dx in dxs] + [(case, round(1 / dx0), c) for c in cfls]:
            if setting not in want:
                want.append(setting)
    assert [(c.params["case"], c.params["cells"], c.params["cfl"]) for c in cells] == want
    shared = [c for c in cells if len(c.labels) == 2]
    assert sorted(c.params["case"] for c in shared) == ["bar", "recontact", "spin"]
    assert all(set(c.labels) == {"dx", "dt"} for c in shared)
    assert load_spec("scenes").path == SPEC_DIR / "scenes.toml" and len(expand(load_spec("scenes"))) == 12


def test_cell_ids_are_stable_and_follow_the_resolved_config(tmp_path):
    """Ids are a hash of the canonical parameters: the same spec gives the same ids (and a different
    label does not change them), while editing the scene config a cell uses gives it a new id."""
    cfg = write(tmp_path, (REPO / "configs" / "recontact.toml").read_text(), "mine.toml")
    text = '[[scene]]\nconfig = "mine.toml"\nvariant = "full"\nparticles = 300\nframes = 2\n'
    first = [c.id for c in expand(load_spec(write(tmp_path, text)))]
    again = [c.id for c in expand(load_spec(write(tmp_path, text.replace("[[scene]]", '[[scene]]\nlabel = "x"'))))]
    assert first == again and len(first) == 1 and len(first[0]) == 12
    cfg.write_text(cfg.read_text().replace("E = 1.0e5", "E = 1.5e5"))
    assert [c.id for c in expand(load_spec(write(tmp_path, text)))] != first
    ids = [c.id for c in expand(load_spec(write(tmp_path, TINY)))]
    assert len(set(ids)) == len(ids) == 6


def test_plan_deals_cells_so_ranks_finish_together_and_keeps_cached_ones():
    """Pending cells go longest-estimated first to the least-loaded rank: every cell exactly once, the
    estimated loads of two ranks within the largest cell of each other (round-robin leaves the full
    accuracy sweep's ranks 28 % apart on an H200), equal costs round-robin; cached cells (on any rank)
    are not dealt again, failed ones only with rerun_failed, and a cached row held only by rank r > 0 is
    sent to rank 0 by r."""
    cells = expand(load_spec("accuracy_full"))
    for world in (2, 3):
        plan = driver.make_plan(cells, [{}] * world, world, rerun_failed=False)
        assert sorted(i for a in plan["assign"] for i in a) == list(range(len(cells)))
        loads = [sum(cells[i].cost for i in a) for a in plan["assign"]]
        assert max(loads) - min(loads) <= max(c.cost for c in cells)
        assert max(loads) < max(sum(c.cost for c in cells[r::world]) for r in range(world))  # beats round-robin
    even = [dataclasses.replace(c, cost=1.0) for c in cells]
    assert driver.deal(even, 3) == [[i for i in range(len(cells)) if i % 3 == r] for r in range(3)]
    ids = [c.id for c in cells]
    statuses = [{ids[0]: "ok", ids[1]: "failed"}, {ids[0]: "ok", ids[2]: "ok"}]
    plan = driver.make_plan(cells, statuses, 2, rerun_failed=False)
    dealt = sorted(i for a in plan["assign"] for i in a)
    assert dealt == [i for i in range(len(cells)) if i not in (0, 1, 2)] and plan["send"] == [[], [ids[2]]]
    assert 1 in [i for a in driver.make_plan(cells, statuses, 2, rerun_failed=True)["assign"] for i in a]


def test_cost_estimates_follow_measured_gpu_times():
    """The estimate that balances ranks tracks what the full accuracy sweep took per cell on an H200
    (figures/accuracy_gpu, 2026-11-22): within 40 % for every cell over 0.5 s, and the same order for
    the three longest."""
    from fracture_gs.sweep.expansion import accuracy_cost

    measured = {("spin", 48, 0.05): 4.94, ("spin", 48, 0.1): 2.49, ("recontact", 64, 0.05): 1.77}
    measured |= {("spin", 96, 0.4): 1.27, ("recontact", 64, 0.1): 1.18, ("bar", 64, 0.05): 0.90}
    for key, seconds in measured.items():
        assert abs(accuracy_cost(*key) / seconds - 1) < 0.4, (key, accuracy_cost(*key))
    top = sorted(measured, key=lambda k: -accuracy_cost(*k))[:3]
    assert top == [("spin", 48, 0.05), ("spin", 48, 0.1), ("recontact", 64, 0.05)]


# ---------------------------------------------------------------- running


@pytest.mark.slow
def test_one_process_sweep_writes_tables_with_the_bench_numbers(single):
    """One process runs every cell and writes sweep.md/.csv/.json (and the Pareto plot); an accuracy
    cell's error is the number the accuracy case function itself gives for that setting."""
    from fracture_gs.paper.accuracy import bar_case

    _, out, code = single
    assert code == 0
    for name in ("sweep.md", "sweep.csv", "sweep.json", "sweep.tex"):
        assert (out / name).is_file(), name
    rows = rows_of(out)
    assert [r["status"] for r in rows] == ["ok"] * 6 and len(list((out / "cells").glob("*.json"))) == 6
    bar = next(r for r in rows if r.get("case") == "bar" and r["cells"] == 16)
    assert bar["error"] == bar_case(1 / 16, 0.8, "cpu").error
    scene = [r for r in rows if r["kind"] == "scene"]
    assert {r["variant"] for r in scene} == {"local_multifield", "full"} and all(r["substeps"] > 0 for r in scene)
    md = (out / "sweep.md").read_text()
    assert "Accuracy cells" in md and "Scene cells" in md and bar["id"] in md
    assert (out / "sweep.csv").read_text().splitlines()[0].startswith("index,id,kind,labels")
    img = cv2.imread(str(out / "sweep_pareto.png"))  # matplotlib is a dev dependency: never skipped
    assert img is not None and 0.01 < (img < 200).any(-1).mean() < 0.6, "the sweep's Pareto figure is blank or filled"


@pytest.mark.slow
def test_two_gloo_ranks_give_the_rows_of_one_process(single, tmp_path):
    """THE distribution test: `torchrun --nproc-per-node 2` (gloo, CPU) splits the cells between two
    processes (as the plan deals them) and rank 0's tables hold exactly the one-process run's metrics,
    every key but wall times and where each cell ran."""
    spec, out1, _ = single
    out2 = tmp_path / "two"
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc-per-node", "2", "--master-addr", "127.0.0.1"]
    cmd += ["--master-port", str(free_port()), str(launcher(tmp_path)), str(spec), "--device", "cpu"]
    proc = subprocess.run(
        [*cmd, "--out", str(out2)], env=child_env(), cwd=tmp_path, capture_output=True, text=True, timeout=TIMEOUT
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    rows1, rows2 = rows_of(out1), rows_of(out2)
    plan = driver.make_plan(expand(load_spec(spec)), [{}, {}], 2, rerun_failed=False)
    assert [r["rank"] for r in rows2] == [0 if i in plan["assign"][0] else 1 for i in range(6)]
    assert {r["world_size"] for r in rows2} == {2}
    assert metrics(rows2) == metrics(rows1)
    for r, mine in enumerate(plan["assign"]):  # one progress line per finished cell, on its own rank
        for k, i in enumerate(mine):
            assert f"[rank {r}/2] {k + 1}/{len(mine)} cell {i + 1}/6" in proc.stdout, proc.stdout[-2000:]


def test_rerun_skips_cached_cells_and_fresh_runs_them_again(single, tmp_path):
    """A second run of the same spec runs no cell (every row comes from OUT/cells, unchanged on disk)
    and gives the same table; --fresh runs every cell again and rewrites its cache file."""
    spec, out1, _ = single
    out = tmp_path / "out"
    shutil.copytree(out1, out)
    before = {p.name: p.read_text() for p in (out / "cells").glob("*.json")}
    lines: list[str] = []
    report = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lines.append))
    assert report.ran == 0 and "0 of 6 cells to run here, 6 cached" in lines[0]
    assert {p.name: p.read_text() for p in (out / "cells").glob("*.json")} == before
    assert report.rows == rows_of(out1)
    fresh = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", fresh=True, echo=lines.append))
    assert fresh.ran == 6 and metrics(fresh.rows) == metrics(report.rows)
    after = {p.name: p.read_text() for p in (out / "cells").glob("*.json")}
    assert after.keys() == before.keys() and all(after[k] != before[k] for k in before)


def test_list_shows_cache_status_without_running(single, tmp_path, capsys):
    """--list prints every cell with its id and cache status (here all cached), runs nothing and creates
    no output folder."""
    spec, out1, _ = single
    assert sweep_main([str(spec), "--out", str(out1), "--list", "--device", "cpu"]) == 0
    out = capsys.readouterr().out
    ids = [r["id"] for r in rows_of(out1)]
    assert "6 ok, 0 failed, 0 to run" in out and all(i in out for i in ids)
    assert sweep_main([str(spec), "--out", str(tmp_path / "empty"), "--list", "--device", "cpu"]) == 0
    assert "0 ok, 0 failed, 6 to run on 1 rank(s)" in capsys.readouterr().out
    assert not (tmp_path / "empty").exists()


def test_failed_cells_are_rows_with_their_sentence_and_exit_1(tmp_path, capsys, monkeypatch):
    """A cell that diverges (a stiff material far over the CFL bound) and a cell whose code raises are
    rows marked failed with their one-line reason; the other cells still run, the tables are written,
    the exit code is 1, a plain rerun keeps the failures and --rerun-failed runs only them again."""
    spec = write(
        tmp_path,
        '[sweep]\nwarmup = false\n[[accuracy]]\ncase = "bar"\ncells = [16, 24]\ncfl = 0.8\n'
        '[[scene]]\nconfig = "recontact"\nvariant = "full"\nparticles = 300\nframes = 2\ncells = 32\ndt = 1e-4\n'
        "[scene.material]\nE = [1e9]\n",
    )
    real = driver.run_cell

    def flaky(cell, device, out_dir=None):
        if cell.kind == "accuracy" and cell.params["cells"] == 24:
            raise RuntimeError("boom in the case function")
        return real(cell, device, out_dir)

    monkeypatch.setattr(driver, "run_cell", flaky)
    out = tmp_path / "out"
    assert sweep_main([str(spec), "--device", "cpu", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("fracture-gs: error: 2 of 3 cells failed") == 1 and "--rerun-failed" in err
    rows = rows_of(out)
    assert [r["status"] for r in rows] == ["ok", "failed", "failed"]
    assert rows[1]["message"] == "RuntimeError: boom in the case function"
    assert rows[2]["message"].startswith("diverged at frame 1: ") and "CFL" in rows[2]["message"]
    # a failed cell has no result: its substep count is 0, not a partial count of the frames that ran
    assert rows[2]["substeps"] == 0 and "\n" not in rows[2]["message"]
    md = (out / "sweep.md").read_text()
    assert "failed: RuntimeError: boom in the case function" in md and "failed: diverged at frame 1" in md
    cached = json.loads((out / "cells" / f"{rows[1]['id']}.json").read_text())["row"]
    assert "Traceback" in cached["traceback"]
    again = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lambda s: None))
    assert again.ran == 0 and len(again.failed) == 2
    monkeypatch.setattr(driver, "run_cell", real)
    retry = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", rerun_failed=True, echo=print))
    assert retry.ran == 2 and [r["status"] for r in retry.rows] == ["ok", "ok", "failed"]


# ---------------------------------------------------------------- devices and launches


def test_nonexistent_device_is_one_sentence(tmp_path, capsys, monkeypatch):
    """--device cuda:K that does not exist is one line naming the device and what exists (exit 2), here
    and on a machine with two GPUs; more ranks on a node than GPUs names both counts and the fix."""
    spec = write(tmp_path, TINY)
    assert sweep_main([str(spec), "--device", "cuda:7", "--out", str(tmp_path / "o")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "--device cuda:7 does not exist" in err[0], err
    monkeypatch.setattr(D, "_cuda", lambda: (2, ""))
    with pytest.raises(D.LaunchError, match=r"cuda:5 does not exist; this machine has 2 CUDA device\(s\), cuda:0 to"):
        D.resolve_device("cuda:5", D.Launch())
    four = D.Launch(rank=3, world_size=4, local_rank=3, local_world_size=4, master="h:1")
    with pytest.raises(
        D.LaunchError, match=r"4 ranks were started on this node but it has 2 GPU\(s\).*nproc-per-node 2"
    ):
        D.resolve_device("cuda", four)
    two = D.Launch(rank=1, world_size=2, local_rank=1, local_world_size=2, master="h:1")
    assert D.resolve_device("cuda", two) == "cuda:1" and D.resolve_device("auto", two) == "cuda:1"
    with pytest.raises(D.LaunchError, match="all 2 ranks on one GPU"):
        D.resolve_device("cuda:0", two)


@pytest.mark.parametrize(
    "env, needle",
    [
        ({"WORLD_SIZE": "2"}, "WORLD_SIZE=2 is set but RANK is not"),
        ({"RANK": "0"}, "RANK=0 is set but WORLD_SIZE is not"),
        ({"LOCAL_RANK": "1"}, "LOCAL_RANK=1 is set but RANK and WORLD_SIZE are not"),
        ({"RANK": "2", "WORLD_SIZE": "2"}, "RANK=2 is outside 0..1"),
        ({"RANK": "x", "WORLD_SIZE": "2"}, "RANK='x' is not an integer"),
        ({"RANK": "0", "WORLD_SIZE": "2"}, "MASTER_ADDR is not set"),
    ],
)
def test_inconsistent_launch_environment_is_one_sentence(env, needle):
    """A half-set torchrun environment is a LaunchError saying which variable is wrong and how to launch."""
    with pytest.raises(D.LaunchError) as info:
        D.launch_from_env(env)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_launch_environment_and_process_group_setup(monkeypatch):
    """torchrun's variables give the launch; with none it is one process. Making the group sets
    NCCL_NVLS_ENABLE=0 when unset, and ranks that cannot meet are one sentence naming the rank and
    the rendezvous address."""
    env = {"RANK": "3", "WORLD_SIZE": "4", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "2"}
    env |= {"MASTER_ADDR": "10.0.0.1", "MASTER_PORT": "29500"}
    assert D.launch_from_env(env) == D.Launch(3, 4, 1, 2, "10.0.0.1:29500")
    assert D.launch_from_env({}) == D.Launch() and not D.Launch().distributed
    assert D.backend_for("cpu") == "gloo"
    monkeypatch.delenv("NCCL_NVLS_ENABLE", raising=False)
    import torch.distributed as dist

    def refuse(*args, **kwargs):
        raise RuntimeError("connect() timed out")

    monkeypatch.setattr(dist, "init_process_group", refuse)
    with pytest.raises(D.LaunchError, match=r"rank 3 could not meet the other 3 rank\(s\) at 10.0.0.1:29500"):
        D.StoreCoordinator(D.launch_from_env(env), "cpu", timeout_s=5).__enter__()
    assert os.environ["NCCL_NVLS_ENABLE"] == "0"


@pytest.mark.slow
def test_a_rank_that_dies_is_named_and_the_tables_are_still_written(tmp_path):
    """Two hand-launched gloo ranks; rank 1 is killed (SIGKILL) after its first cell. Rank 0 finishes its
    own cells, notices the silence within --rank-timeout, writes the tables with rank 1's unfinished
    cells marked missing (its finished cell is read from the shared cache) and exits 3 with one line
    naming rank 1; rerunning resumes only the missing cells."""
    spec = write(tmp_path, '[sweep]\nwarmup = false\n[[accuracy]]\ncase = "spin"\ncells = 16\n')
    spec.write_text(spec.read_text() + "cfl = [0.2, 0.25, 0.3, 0.35, 0.4, 0.45]\n")
    out = tmp_path / "out"
    args = [sys.executable, str(launcher(tmp_path)), str(spec), "--device", "cpu", "--out", str(out)]
    args += ["--rank-timeout", "4"]
    env = child_env(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(free_port()), WORLD_SIZE="2")
    ranks = [
        subprocess.Popen(
            args, env={**env, "RANK": str(r)}, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for r in (0, 1)
    ]
    try:
        for line in ranks[1].stdout:
            if "[rank 1/2] 1/3 cell" in line:
                ranks[1].send_signal(signal.SIGKILL)
                break
        ranks[1].wait(timeout=TIMEOUT)
        out0, err0 = ranks[0].communicate(timeout=TIMEOUT)
    finally:
        for p in ranks:
            if p.poll() is None:
                p.kill()
    assert ranks[1].returncode == -signal.SIGKILL
    assert ranks[0].returncode == 3, out0 + err0
    err = [line for line in err0.splitlines() if line.startswith("fracture-gs: error:")]
    assert len(err) == 1 and "rank 1 of 2 sent no heartbeat for 4 s" in err[0] and "rerunning" in err[0], err0
    rows = rows_of(out)
    plan = driver.make_plan(expand(load_spec(spec)), [{}, {}], 2, rerun_failed=False)
    lost = plan["assign"][1][1:]  # rank 1 finished its first cell only
    assert [r["status"] for r in rows] == ["missing" if i in lost else "ok" for i in range(6)], rows
    assert all("rank 1 stopped" in r["message"] for r in rows if r["status"] == "missing")
    resumed = driver.run_sweep(spec, driver.SweepOptions(out_dir=out, device="cpu", echo=lambda s: None))
    assert resumed.ran == 2 and [r["status"] for r in resumed.rows] == ["ok"] * 6


def test_help_teaches_the_launches(capsys):
    """`fracture-gs sweep --help` shows examples for one process, torchrun on GPUs and on CPUs, and the exit codes."""
    assert sweep_main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "examples:" in text and "fracture-gs sweep" in text and "--nproc-per-node 2" in text
    assert "--device cuda" in text and "--device cpu" in text and "exit codes:" in text
