"""`sim/providers/replay.py` and `sim/providers/broadcast.py`: a saved or live history of topologies is
latched snapshot by snapshot at the first frame end at or after each one's latch frame, the provider's
`topology` is the newest snapshot, and a follower waits for the leader's frame (and only as long as its
timeout allows). Unit-level: the providers read only frame, time and device from the simulator."""

import threading
import time
import types

import pytest
import torch

from fracture_gs.sim.providers.broadcast import BroadcastProvider, FileChannel, LeaderProvider, MemoryChannel
from fracture_gs.sim.providers.replay import ReplayProvider
from fracture_gs.sim.topology import Topology


def _topo(frame, tag):
    """A two-particle snapshot latched at `frame`, told apart by its fragment labels (`tag`)."""
    return Topology(
        fragment=torch.tensor([0, tag], dtype=torch.int32),
        band=torch.zeros(2, dtype=torch.int32),
        normal=(1.0, 0.0, 0.0),
        point=(0.0, 0.0, 0.0),
        latch_frame=frame,
        latch_time=0.1 * frame,
    )


def _sim(frame):
    return types.SimpleNamespace(frame=frame, time=0.05 * frame, device="cpu")


def test_replay_topology_is_the_newest_snapshot_of_the_history():
    """`ReplayProvider.topology` is the last snapshot of the history (what the run ends with), whatever
    has been latched so far."""
    history = [_topo(1, 1), _topo(3, 2), _topo(5, 3)]
    p = ReplayProvider(history)
    assert p.topology is history[2]
    assert ReplayProvider(history[0]).topology is history[0]


def test_replay_latches_each_snapshot_at_its_frame_and_skips_to_the_newest_due():
    """Snapshot i latches at the first frame end ≥ its latch frame, once, stamped with the replaying run's
    time and frame; a frame that passes several latch frames at once returns the newest of them."""
    history = [_topo(1, 1), _topo(3, 2), _topo(5, 3), _topo(6, 4)]
    p = ReplayProvider(history)
    assert p(_sim(0)) is None
    got = p(_sim(1))
    assert got.fragment.tolist() == [0, 1] and got.latch_frame == 1 and got.latch_time == 0.05
    assert p(_sim(2)) is None
    assert p(_sim(3)).fragment.tolist() == [0, 2]
    got = p(_sim(7))  # frames 5 and 6 both passed
    assert got.fragment.tolist() == [0, 4] and got.latch_frame == 7
    assert p(_sim(8)) is None


def test_file_channel_follower_waits_for_the_leaders_frame(tmp_path):
    """A follower asking for frame f blocks until the leader has published frame f (here 0.2 s later), then
    sees what latched up to f."""
    folder = tmp_path
    ch = FileChannel(folder, timeout=30.0, poll=0.005)
    t = threading.Timer(0.2, lambda: ch.publish(0, _topo(0, 4)))
    t0 = time.monotonic()
    t.start()
    got = FileChannel(folder, timeout=30.0, poll=0.005).up_to(0)
    t.join()
    assert time.monotonic() - t0 >= 0.15
    assert [g.fragment.tolist() for g in got] == [[0, 4]]


def test_file_channel_gives_up_after_its_timeout(tmp_path):
    """A leader that never reaches the frame ends the follower's wait with a TimeoutError after `timeout`
    seconds, not before."""
    folder = tmp_path
    ch = FileChannel(folder, timeout=0.3, poll=0.01)
    t0 = time.monotonic()
    with pytest.raises(TimeoutError, match="frame 2"):
        ch.up_to(2)
    assert 0.25 <= time.monotonic() - t0 < 5.0


def test_file_channel_reads_frame_numbers_past_five_digits(tmp_path):
    """Frames are numbered by the whole number in their file name: frames 100001 and 200001 are two
    frames, both latched topologies reach the follower, and a frame after the one asked for does not."""
    folder = tmp_path
    ch = FileChannel(folder, timeout=5.0)
    ch.publish(100001, _topo(100001, 1))
    ch.publish(150000, None)
    ch.publish(200001, _topo(200001, 2))
    ch.publish(300001, _topo(300001, 3))
    got = FileChannel(folder, timeout=5.0).up_to(200001)
    assert [g.fragment.tolist() for g in got] == [[0, 1], [0, 2]]


def test_broadcast_follower_latches_what_the_leader_latched():
    """Leader and follower in threads of one process (`MemoryChannel`): the follower latches the leader's
    topologies at the same frames, and nothing at other frames."""
    ch = MemoryChannel(timeout=5.0)
    leader = LeaderProvider(lambda sim: _topo(sim.frame, sim.frame + 5) if sim.frame in (2, 3) else None, ch)
    follower = BroadcastProvider(ch)
    for frame in range(5):
        leader(_sim(frame))
        got = follower(_sim(frame))
        assert (got is not None) is (frame in (2, 3))
    assert follower.topology.fragment.tolist() == [0, 8]
    assert ch.first().latch_frame == 2  # the first latch, not the newest


def test_memory_channel_gives_up_after_its_timeout():
    """A MemoryChannel follower whose leader never reaches the frame raises TimeoutError after its timeout."""
    ch = MemoryChannel(timeout=0.2)
    ch.publish(0, None)
    with pytest.raises(TimeoutError, match="frame 1"):
        ch.up_to(1)
    assert ch.up_to(0) == []
