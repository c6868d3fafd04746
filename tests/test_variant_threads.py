"""render-sim's variants at once on one device, a thread each (`--schedule threads`, `fracture_gs.render_sim.threads`).

The leader's topology reaches the followers through a `MemoryChannel` at the end of each of its frames,
so a follower latches at the frame a replay of the saved history would: on the CPU (deterministic kernels)
every variant's per-frame metrics, the latched topology and every comparison frame equal the run in
turn's, bit for bit. An interrupt or an error in one variant stops the others at their next frame."""

import json
import threading
import time

import numpy as np
import pytest
import torch
from runutil import assert_same_run, tiny_bread

from fracture_gs import pipeline
from fracture_gs import render_sim as runner
from fracture_gs.io.video import read_video
from fracture_gs.render_sim import variant as render_variant
from fracture_gs.runtime import current_lane, stream_lane
from fracture_gs.sim.providers.broadcast import MemoryChannel
from fracture_gs.sim.topology import Topology

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.mark.slow
def test_threads_equal_the_run_in_turn(tmp_path):
    variants = ["stress_zero", "full", "baseline"]
    runner.run_render_sim(tiny_bread(), variants, "cpu", tmp_path / "turn", schedule="in_turn")
    runner.run_render_sim(tiny_bread(), variants, "cpu", tmp_path / "side", schedule="threads")
    assert_same_run(tmp_path / "turn", tmp_path / "side", variants)
    names = sorted(p.name for p in (tmp_path / "turn" / "frames").glob("compare_*.png"))
    assert len(names) == 15 and names == sorted(p.name for p in (tmp_path / "side" / "frames").glob("compare_*.png"))
    for n in names:  # composed live from the leader's first latch on: the same pictures, insets included
        assert (tmp_path / "turn" / "frames" / n).read_bytes() == (tmp_path / "side" / "frames" / n).read_bytes(), n
    assert read_video(tmp_path / "side" / "comparison.mp4")[0] == 15
    s = json.loads((tmp_path / "side" / "summary.json").read_text())
    assert [v["status"] for v in s["variants"]] == ["ok"] * 3
    assert not list((tmp_path / "side").glob(".*")), "no temporary files left"


def test_memory_channel_waits_for_the_leader_and_stops_when_it_closes():
    """A follower waits for the leader's frame f (timing out if it never comes), wakes when another thread
    publishes it, sees exactly the topologies latched at frames <= f, and stops waiting once the leader closes."""
    channel = MemoryChannel(timeout=0.2)
    channel.publish(0, None)
    assert channel.up_to(0) == [] and channel.first() is None
    with pytest.raises(TimeoutError):
        channel.up_to(3)
    topo = Topology(torch.tensor([0, 1, 1]), torch.tensor([0, 1, 0]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=2)
    later = Topology(torch.tensor([0, 1, 2]), torch.tensor([0, 1, 2]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=4)
    channel.timeout = 30.0

    def leader():
        time.sleep(0.05)
        channel.publish(1, None)
        channel.publish(2, topo)
        channel.publish(4, later)

    t = threading.Thread(target=leader)
    t.start()
    got = channel.up_to(2)  # blocks until the leader's thread has published frame 2
    t.join()
    assert len(got) == 1 and got[0].latch_frame == 2 and torch.equal(got[0].fragment, topo.fragment)
    assert channel.first().latch_frame == 2
    channel.close()
    assert [t.latch_frame for t in channel.up_to(9)] == [2, 4]


def test_an_interrupted_variant_stops_the_others_at_their_next_frame(tmp_path, monkeypatch):
    """Ctrl-C inside one variant's frame: that variant and the ones beside it stop at their next frame, each
    with an "interrupted at frame N" row; the run raises KeyboardInterrupt with its outputs kept."""
    cfg = tiny_bread(20)
    real = pipeline.simulate

    def interrupt_full(sim, cov0, frames, frame_dt, **kw):
        for out in real(sim, cov0, frames, frame_dt, **kw):
            if sim.cfg.variant == "full" and out.frame == 3:
                raise KeyboardInterrupt
            yield out

    monkeypatch.setattr(render_variant, "simulate", interrupt_full)
    with pytest.raises(KeyboardInterrupt):
        runner.run_render_sim(cfg, ["full", "baseline"], "cpu", tmp_path, schedule="threads")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interrupted"] is True
    status = {v["variant"]: v["status"] for v in summary["variants"]}
    assert status["full"] == "interrupted at frame 2"
    assert status["baseline"].startswith("interrupted at frame"), status
    last = int(status["baseline"].rsplit(" ", 1)[1])
    assert last < cfg.frames - 1, "the variant beside it stopped early"
    assert (tmp_path / "comparison.mp4").exists()


def test_an_error_in_one_variant_is_raised_and_stops_the_others(tmp_path, monkeypatch):
    """An exception inside one variant's thread reaches the caller as itself (type and message), after the
    other variants have stopped at their next frame."""
    cfg = tiny_bread(30)
    real = pipeline.simulate
    seen = {}

    def fail_baseline(sim, cov0, frames, frame_dt, **kw):
        for out in real(sim, cov0, frames, frame_dt, **kw):
            seen[sim.cfg.variant] = out.frame
            if sim.cfg.variant == "baseline" and out.frame == 2:
                raise ValueError("boom in baseline")
            yield out

    monkeypatch.setattr(render_variant, "simulate", fail_baseline)
    with pytest.raises(ValueError, match="boom in baseline"):
        runner.run_render_sim(cfg, ["full", "baseline"], "cpu", tmp_path, schedule="threads")
    assert seen["full"] < cfg.frames, "the leader stopped instead of running to the end"


def test_a_run_that_never_latches_in_threads(tmp_path):
    """Too few frames to latch: no live composing starts (it waits for the first latch), the comparison is
    composed after the run, no topology.npz is written, and every variant is ok."""
    summary = runner.run_render_sim(tiny_bread(2), ["full", "baseline"], "cpu", tmp_path, schedule="threads")
    assert [v["status"] for v in summary.variants] == ["ok", "ok"]
    assert not (tmp_path / "topology.npz").exists()
    assert read_video(tmp_path / "comparison.mp4")[0] == 3


def test_stream_lanes_are_per_thread_and_the_render_worker_inherits_its_producers(monkeypatch):
    """`stream_lane` sets the lane of the calling thread only (nested blocks restore it), and a variant's
    render worker draws in the lane of the thread that made it: variant threads never share a stream."""
    assert current_lane() == 0
    seen = {}
    with stream_lane(2):
        t = threading.Thread(target=lambda: seen.setdefault("other", current_lane()))
        t.start()
        t.join()
        with stream_lane(5):
            assert current_lane() == 5
        assert current_lane() == 2

        class Painter:
            def __call__(self, out):
                seen["render"] = current_lane()
                return np.zeros((4, 4, 3), np.uint8)

        class Out:
            means = torch.zeros(1, 3)
            ready = None

        monkeypatch.setattr(render_variant, "VideoWriter", lambda path, fps: _null_video())
        sink = render_variant.FrameSink(Painter(), "unused.mp4", 10, [])
        sink.put(Out())
        sink.close()
    assert current_lane() == 0
    assert seen == {"other": 0, "render": 2}


def _null_video():
    class Null:
        def write(self, img):
            pass

        def close(self):
            pass

    return Null()


def test_the_schedule_is_in_turn_unless_threads_are_asked_for():
    """In turn is the Python API's default (threads were 4 % faster on 2 CPU cores and not faster on an H200, and
    interleave metrics.jsonl's rows; the CLI asks for `auto`); a wrong name is one sentence."""
    import inspect

    assert inspect.signature(runner.run_render_sim).parameters["schedule"].default == "in_turn"
    expected = "schedule must be 'auto', 'in_turn', 'threads' or 'processes', got 'sideways'"
    with pytest.raises(ValueError, match=expected):
        runner.run_render_sim(tiny_bread(1), ["full"], "cpu", "unused", schedule="sideways")
