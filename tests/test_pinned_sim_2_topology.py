"""A snapshot made by hand (paper benchmarks, tests) without naming its latch frame is latched at frame 0,
the run's start: followers and the differentiable solver apply it from the first frame and the paper's
tables report latch frame 0."""

import torch

from fracture_gs.sim.topology import Topology


def test_a_snapshot_without_a_latch_frame_is_latched_at_frame_zero(tmp_path):
    """The default latch frame is 0 (a frame index; −1 is no frame of the run), and it survives a save and
    load."""
    t = Topology(fragment=torch.tensor([0, 1]), band=torch.tensor([1, 1]), normal=(0.0, 0.0, 1.0), point=(0, 0, 0))
    assert t.latch_frame == 0
    t.save(tmp_path / "t.npz")
    assert Topology.load(tmp_path / "t.npz").latch_frame == 0
