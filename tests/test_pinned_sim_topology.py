"""`sim/topology.py`: a saved topology reads back with every field it was saved with, a file from before
`pair_radius` / `release_events` / `events` existed reads back with the documented defaults (1.5 Δx, the
first event's band released, no events), and the plane labels put fragment 1 on the normal's side."""

import numpy as np
import torch

from fracture_gs.sim.topology import FractureEvent, Topology, load_history, save_history


def _topo(tag, pair_radius=2.5, release_events=3):
    return Topology(
        fragment=torch.tensor([0, 1, tag], dtype=torch.int32),
        band=torch.tensor([0, 2, 1], dtype=torch.int32),
        normal=(0.0, 1.0, 0.0),
        point=(0.5, 0.25, 0.0),
        latch_time=0.125,
        latch_frame=4,
        pair_radius=pair_radius,
        release_events=release_events,
        events=[FractureEvent("plane", 0.125, 4, (-1,), (0, 1), (0.5, 0.25, 0.0), (0.0, 1.0, 0.0))],
    )


def test_saved_history_reads_back_every_field_of_every_snapshot(tmp_path):
    """save_history → load_history returns each snapshot's labels, plane, latch, pair radius, release count
    and events as saved; Topology.load gives the newest."""
    a, b = _topo(1, pair_radius=2.5, release_events=3), _topo(2, pair_radius=0.75, release_events=0)
    save_history(tmp_path / "t.npz", [a, b])
    back = load_history(tmp_path / "t.npz")
    for got, want in zip(back, (a, b)):
        assert torch.equal(got.fragment, want.fragment) and torch.equal(got.band, want.band)
        assert (got.normal, got.point, got.latch_time, got.latch_frame) == (
            want.normal,
            want.point,
            want.latch_time,
            want.latch_frame,
        )
        assert got.pair_radius == want.pair_radius and got.release_events == want.release_events
        assert got.events == want.events
    last = Topology.load(tmp_path / "t.npz")
    assert last.fragment.tolist() == [0, 1, 2] and last.pair_radius == 0.75 and last.release_events == 0


def test_a_file_without_the_newer_fields_reads_with_their_defaults(tmp_path):
    """A topology.npz written before `pair_radius`, `release_events` and `events` were saved loads with
    pair radius 1.5 Δx, release of the first event's band (1) and no events."""
    arrays = _topo(1)._arrays()
    for key in ("pair_radius", "release_events", "events"):
        arrays.pop(key)
    np.savez_compressed(tmp_path / "old.npz", **arrays)
    t = Topology.load(tmp_path / "old.npz")
    assert t.pair_radius == 1.5 and t.release_events == 1 and t.events == []
    assert t.fragment.tolist() == [0, 1, 1]


def test_plane_labels_put_fragment_one_on_the_normals_side():
    """from_plane: fragment 1 where (x − p)·n̂ ≥ 0 (the plane itself included), band where the distance is
    strictly below band_width; the normal is stored normalized."""
    x = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.75, 0.0], [0.0, 1.0, 0.0], [0.0, 1.25, 0.0], [0.0, 2.0, 0.0]])
    t = Topology.from_plane(x, (0.0, 1.0, 0.0), (0.0, 4.0, 0.0), 0.25)
    assert t.fragment.tolist() == [0, 0, 1, 1, 1]
    assert t.band.tolist() == [0, 0, 1, 0, 0]
    assert t.normal == (0.0, 1.0, 0.0) and t.n_fragments == 2
    assert t.counts() == {"fragment0": 2, "fragment1": 3, "band": 1}
