"""How a `Topology` snapshot is derived from another (`sim/topology.py`):

- `permuted(order)` is the same snapshot for particles reordered as the simulator sorts them (new i = old
  order[i]): fragment ids AND band flags move with their particles; the plane, latch and events do not change;
- `refined(fragment, band, event)` is the snapshot after one more event: the labels replaced (as int32), the latch
  time and frame taken from the new event, the event appended to a NEW list (the earlier snapshot keeps its own
  history), and n_Π, its point, the pair radius and the released events kept from the first;
- `from_plane` records its cut as the first event: a plane event at the latch time and frame, cutting the unbroken
  object (−1) into fragments 0 and 1, with the plane's point and unit normal."""

import torch

from fracture_gs.sim.topology import FractureEvent, Topology


def _first():
    x = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 0.05], [0.0, 0.0, 2.0], [0.0, 0.0, -0.05], [0.0, 0.0, 0.0]])
    return Topology.from_plane(
        x, (0.0, 0.0, 0.0), (0.0, 0.0, 2.0), 0.1, latch_time=0.25, latch_frame=5, pair_radius=2.0
    )


def test_from_plane_records_its_cut_as_the_first_event():
    """Normal (0, 0, 2) is stored as (0, 0, 1); labels by side (0 below, 1 above and on the plane); band
    within 0.1 m; one event: plane, t = 0.25 s, frame 5, parents (−1,), children (0, 1), point and unit normal."""
    t = _first()
    assert t.fragment.dtype == torch.int32 and t.fragment.tolist() == [0, 1, 1, 0, 1]
    assert t.band.tolist() == [0, 1, 0, 1, 1]
    assert t.normal == (0.0, 0.0, 1.0) and t.point == (0.0, 0.0, 0.0)
    assert (t.latch_time, t.latch_frame, t.pair_radius) == (0.25, 5, 2.0)
    assert t.events == [FractureEvent("plane", 0.25, 5, (-1,), (0, 1), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))]


def test_permuted_moves_labels_and_band_with_their_particles():
    """order = [2, 0, 3, 1, 4]: fragment [1, 0, 0, 1, 1] and band [0, 0, 1, 1, 1]; everything else as before."""
    t = _first()
    p = t.permuted(torch.tensor([2, 0, 3, 1, 4]))
    assert p.fragment.tolist() == [1, 0, 0, 1, 1]
    assert p.band.tolist() == [0, 0, 1, 1, 1]
    assert (p.normal, p.point, p.latch_time, p.latch_frame, p.events) == (
        t.normal,
        t.point,
        t.latch_time,
        t.latch_frame,
        t.events,
    )


def test_refined_replaces_labels_and_appends_the_event_to_a_new_history():
    """A second cut at t = 0.5 s, frame 9, splitting fragment 1 into 1 and 2: labels and band replaced (int64 in,
    int32 out), latch time and frame from the event, two events in the new snapshot and still one in the first;
    the first event's plane, the pair radius and the released events stay."""
    t = _first()
    t.release_events = 2
    cut = FractureEvent("plane", 0.5, 9, (1,), (1, 2), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0))
    r = t.refined(torch.tensor([0, 1, 2, 0, 1]), torch.tensor([0, 2, 2, 1, 0]), cut)
    assert r.fragment.dtype == torch.int32 and r.band.dtype == torch.int32
    assert r.fragment.tolist() == [0, 1, 2, 0, 1] and r.band.tolist() == [0, 2, 2, 1, 0]
    assert (r.latch_time, r.latch_frame) == (0.5, 9)
    assert r.events == [t.events[0], cut] and len(t.events) == 1
    assert (r.normal, r.point, r.pair_radius, r.release_events) == ((0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 2.0, 2)
    assert r.n_fragments == 3 and t.n_fragments == 2
