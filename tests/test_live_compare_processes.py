"""The CPU's processes schedule composes the comparison while its workers run (`multi_device`, `frame_files`).

A worker writes each drawn frame as a file of its own the moment it is drawn (temporary name, then renamed); the
parent reads them in order as they appear and, from the leader's first latch on (read from the topology channel,
`FileChannel.first`), composes the comparison beside the variants instead of after the last one. The rules: a
reader sees only whole frames, in order; the first latch is the first topology published, whatever came later;
and a run in processes hands back a comparison that was composed live, with every frame of every variant.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from fracture_gs.render_sim.frame_files import FrameFiles
from fracture_gs.sim.providers.broadcast import FileChannel
from fracture_gs.sim.topology import Topology


def _frame(k: int) -> np.ndarray:  # [6, 8, 3] uint8, different for every k
    return (np.arange(6 * 8 * 3, dtype=np.int64).reshape(6, 8, 3) * (k + 3) % 251).astype(np.uint8)


def test_a_reader_sees_the_written_frames_in_order_and_no_partial_one(tmp_path):
    """Frames appended in one process are read back in another's reader in order and equal; a temporary file (a
    frame being written) is not counted; frames read stay readable after the folder is removed."""
    writer, reader = FrameFiles(tmp_path / "v"), FrameFiles(tmp_path / "v")
    assert len(reader) == 0
    for k in range(3):
        writer.append(_frame(k))
    (tmp_path / "v" / ".frame_000003.123.tmp.npy").write_bytes(b"half a frame")
    assert len(writer) == len(reader) == 3
    assert all(np.array_equal(reader[k], _frame(k)) for k in range(3))
    writer.append(_frame(3))
    assert len(reader) == 4 and np.array_equal(reader[3], _frame(3))
    frames = list(reader)
    reader.remove()
    assert not (tmp_path / "v").exists() and len(frames) == 4 and np.array_equal(reader[2], _frame(2))


def _topology(latch_frame: int) -> Topology:
    return Topology(
        torch.tensor([0, 1]), torch.tensor([0, 1]), (1.0, 0.0, 0.0), (0.5, 0.0, 0.0), latch_frame=latch_frame
    )


def test_first_is_the_first_latch_published_without_waiting(tmp_path):
    """`FileChannel.first` answers at once: None while the leader has latched nothing (frames published with no
    topology, or none yet), then the earliest latch, also once a later one is published."""
    leader, reader = FileChannel(tmp_path / "ch"), FileChannel(tmp_path / "ch", timeout=0.1)
    assert reader.first() is None
    leader.publish(0, None)
    leader.publish(1, None)
    assert reader.first() is None
    leader.publish(2, _topology(2))
    leader.publish(3, None)
    leader.publish(4, _topology(4))
    assert reader.first().latch_frame == 2
    assert FileChannel(tmp_path / "ch").first().latch_frame == 2  # a fresh reader too


def draw_five(ctx, variant, painter, metrics_file, frames_store, provider=None, stop=None, position=0):
    """A run_variant stand-in (module level, so a spawned worker imports it): five frames of a colour of its own,
    the leader publishing a latch at frame 2."""
    import time

    from fracture_gs.render_sim import VariantSummary
    from fracture_gs.sim.providers.broadcast import LeaderProvider

    leader = isinstance(provider, LeaderProvider)
    for k in range(5):
        img = np.full((48, 64, 3), (40 * k + 17 * len(variant)) % 256, np.uint8)
        frames_store.append(img)
        if leader:
            provider.channel.publish(k, _topology(2) if k == 2 else None)
        time.sleep(0.05)
    return VariantSummary(variant, "ok", 4, 0, 0.0, None, None, None, interrupted=False), None


@pytest.mark.slow
def test_processes_on_one_cpu_compose_the_comparison_while_the_variants_run(tmp_path):
    """Two variants in a parent and a spawned worker on the CPU: the result carries the comparison composed live
    (started from the leader's latch), whose frames are the variants' frames; finished, it writes comparison.mp4,
    and no frame file is left behind."""
    import io

    from runutil import tiny_bread

    from fracture_gs import assets
    from fracture_gs.render_sim.context import RunContext
    from fracture_gs.render_sim.multi_device import run_on_devices

    order = ("stress_zero", "full")
    ctx = RunContext(tiny_bread(5), assets.build("bread", size="small", n=300), None, "cpu", tmp_path, order, order)
    result = run_on_devices(ctx, ["cpu", "cpu"], io.StringIO(), run=draw_five)
    assert result.live is not None
    assert [len(result.frames[v]) for v in order] == [5, 5]
    for v, panel in zip(order, result.live.frame_lists):
        assert len(panel) == 5 and all(np.array_equal(a, b) for a, b in zip(result.frames[v], panel))
    result.live.finish(["ok", "ok"])
    assert (tmp_path / "comparison.mp4").stat().st_size > 0
    assert not (tmp_path / ".frames").exists()
