"""`render-sim --devices`: variants side by side on several devices, the leader's topology handed to
the others as it latches. On the CPU two worker processes stand in for two GPUs: every variant's
per-frame metrics and its latched topology equal those of the sequential run (bitwise, since the
CPU kernels are deterministic). The workers are processes, as on GPUs."""

import json

import numpy as np
import pytest
import torch
from runutil import assert_same_run, tiny_bread

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.render_sim import RunContext
from fracture_gs.render_sim import variant as render_variant
from fracture_gs.sim.providers.broadcast import FileChannel
from fracture_gs.sim.topology import Topology

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.mark.slow
def test_two_workers_match_the_sequential_run(tmp_path):
    variants = ["stress_zero", "full", "baseline"]
    runner.run_render_sim(tiny_bread(), variants, "cpu", tmp_path / "seq")
    runner.run_render_sim(tiny_bread(), variants, "cpu", tmp_path / "par", devices=["cpu", "cpu"])
    assert_same_run(tmp_path / "seq", tmp_path / "par", variants)
    assert (tmp_path / "par" / "comparison.mp4").exists()
    s = json.loads((tmp_path / "par" / "summary.json").read_text())
    assert [v["status"] for v in s["variants"]] == ["ok"] * 3


def test_channel_waits_for_the_leader_and_stops_when_it_closes(tmp_path):
    """A follower waits for the leader's frame f (timing out if it never comes), sees exactly the topologies
    latched at frames <= f (a later latch stays hidden), and stops waiting once the leader closes."""
    leader, follower = FileChannel(tmp_path / "ch"), FileChannel(tmp_path / "ch", timeout=0.2)
    leader.publish(0, None)
    assert follower.up_to(0) == []
    with pytest.raises(TimeoutError):
        follower.up_to(3)
    topo = Topology(torch.tensor([0, 1, 1]), torch.tensor([0, 1, 0]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=2)
    later = Topology(torch.tensor([0, 1, 2]), torch.tensor([0, 1, 2]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=4)
    leader.publish(2, topo)
    leader.publish(4, later)
    got = follower.up_to(2)
    assert len(got) == 1 and got[0].latch_frame == 2 and torch.equal(got[0].fragment, topo.fragment)
    leader.close()
    assert [t.latch_frame for t in follower.up_to(9)] == [2, 4]


def test_devices_flag_errors_are_one_line(capsys):
    """A device list naming a GPU this machine lacks, or no device, is one line (on a machine without CUDA:
    CUDA is not available; with it: which devices exist)."""
    missing = f"cuda:{torch.cuda.device_count() if torch.cuda.is_available() else 1}"
    assert cli.main(["render-sim", "bread", "--devices", f"cuda:0,{missing}"]) == 2
    err = capsys.readouterr().err
    want = "does not exist; this machine has" if torch.cuda.is_available() else "CUDA is not available"
    assert err.count("\n") == 1 and want in err
    assert cli.main(["render-sim", "bread", "--devices", ","]) == 2
    assert "names no device" in capsys.readouterr().err


def explode(ctx, variant, *args, **kwargs):
    """A run_variant stand-in that fails (module level, so a spawned worker can import it)."""
    raise ValueError(f"boom in {variant}")


@pytest.mark.slow
def test_a_failing_worker_is_reported_with_its_error(tmp_path):
    """An error inside a worker process reaches the caller as WorkerFailed naming the device, the error and
    the worker's traceback; the other workers stop and no temporary files are left behind."""
    import io

    from fracture_gs.render_sim.multi_device import WorkerFailed, run_on_devices

    ctx = _context(tmp_path)
    with pytest.raises(WorkerFailed, match=r"the worker on cpu failed: ValueError: boom in stress_zero") as err:
        run_on_devices(ctx, ["cpu", "cpu"], io.StringIO(), run=explode)
    assert "Traceback" in str(err.value)
    assert not list(tmp_path.glob(".*"))


@pytest.mark.slow
def test_a_run_that_never_latches_on_two_workers(tmp_path):
    """Too few frames for the stress event to latch: both workers finish, no topology.npz is written (as in
    the sequential run) and every variant is ok (an empty history once crashed the topology writer)."""
    cfg = tiny_bread()
    cfg.frames = 2
    summary = runner.run_render_sim(cfg, ["full", "baseline"], "cpu", tmp_path / "par", devices=["cpu", "cpu"])
    assert [v["status"] for v in summary.variants] == ["ok", "ok"]
    assert not (tmp_path / "par" / "topology.npz").exists() and (tmp_path / "par" / "comparison.mp4").exists()


def _context(out_dir):
    """A two-variant run's context on a 300-particle bread (the leader stress_zero first)."""
    from fracture_gs import assets

    gs = assets.build("bread", size="small", n=300)
    order = ("stress_zero", "full")
    return RunContext(tiny_bread(), gs, None, "cpu", out_dir, order, order)


def crash_the_follower(ctx, variant, *args, **kwargs):
    """A run_variant stand-in: the follower's process dies without a word (as on a segfault or the OOM
    killer); the leader returns at once."""
    import os

    if variant == "full":
        os._exit(3)
    from fracture_gs.render_sim import VariantSummary

    return VariantSummary(variant, "ok", 0, 0, 0.0, None, None, None, interrupted=False), None


@pytest.mark.slow
def test_a_worker_process_that_dies_is_named(tmp_path):
    """A worker process that exits without reporting (killed, crashed) is a WorkerFailed naming the process
    and its exit code, not a hang and not a silently missing variant."""
    import io

    from fracture_gs.render_sim.multi_device import WorkerFailed, run_on_devices

    with pytest.raises(WorkerFailed, match=r"worker process fgs-cpu-1 exited with code 3 before reporting"):
        run_on_devices(_context(tmp_path), ["cpu", "cpu"], io.StringIO(), run=crash_the_follower)


def test_each_variant_paints_with_its_own_exposed_interior_colours():
    """The exposed-interior colours follow one variant's fracture: a variant's painter starts without
    the previous variant's colours (two render threads never share them) and shares the scene's tensors."""
    from fracture_gs.pipeline import prepare_scene

    scene = prepare_scene(tiny_bread(), "cpu")
    painter = runner.Painter(scene.gaussians, scene.cfg, "cpu")
    painter.exposed_rgb, painter.exposed_count = torch.ones(3, 3), 3  # left by a previous variant
    fresh = painter.for_variant()
    assert fresh.exposed_rgb is None and fresh.exposed_count == 0
    assert painter.exposed_count == 3 and fresh.cov0 is painter.cov0 and fresh.sh is painter.sh


def test_frame_sink_draws_what_the_painter_draws(device, tmp_path):
    """The render worker draws each queued frame exactly as the painter does on the caller's thread: on
    CUDA on its own stream, after the event `put` records behind the producer's copies (the frames'
    tensors are rewritten right after `put`, as the solver does, so a worker that ran early or read
    recycled memory would draw something else)."""
    from fracture_gs.pipeline import FrameOutput, prepare_scene

    scene = prepare_scene(tiny_bread(), device)
    gs = scene.gaussians
    painter = runner.Painter(gs, scene.cfg, device)
    n = len(gs)
    state = gs.means.clone()  # the solver's state, moved in place between frames

    def frame(k):
        state.add_(0.01)
        eye = torch.eye(3, device=device).expand(n, 3, 3)
        return FrameOutput(
            k, 0.1 * k, state.clone(), eye.clone(), painter.cov0, torch.full((n,), -1, device=device),
            torch.zeros(n, device=device),
        )  # fmt: skip

    direct = painter.for_variant()
    want = [direct(frame(k)) for k in range(4)]
    state.copy_(gs.means)
    store: list = []
    sink = render_variant.FrameSink(painter.for_variant(), tmp_path / "v.mp4", 10, store)
    for k in range(4):
        sink.put(frame(k))
    state.mul_(0.0)  # the solver moving on must not reach the frames already queued
    sink.close()
    assert len(store) == 4
    for a, b in zip(store, want):
        assert np.array_equal(a, b)


@pytest.mark.slow
def test_painter_draws_the_same_with_and_without_the_topology_version(device):
    """A painter that knows each frame's topology version (and so finds the visible Gaussians only when a
    fracture changed them) draws every frame of a run, before and after the latch and with exposed
    interior, exactly as one that recomputes them every frame (version unknown)."""
    from fracture_gs.pipeline import FrameOutput, make_simulator, prepare_scene, simulate

    cfg = tiny_bread()
    scene = prepare_scene(cfg, device)
    painter = runner.Painter(scene.gaussians, scene.cfg, device)
    known, unknown = painter.for_variant(), painter.for_variant()
    sim = make_simulator(scene.cfg, scene.gaussians, "full", device)
    versions = set()
    for out in simulate(sim, painter.cov0, cfg.frames, cfg.frame_dt):
        blind = FrameOutput(out.frame, out.time, out.means, out.F, out.cov0, out.fragment, out.band)
        assert np.array_equal(known(out), unknown(blind)), out.frame
        versions.add(out.topology_version)
    assert versions == {0, 1} and known.exposed_count > 0, (versions, known.exposed_count)
