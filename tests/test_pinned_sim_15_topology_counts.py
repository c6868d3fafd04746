"""`Topology.n_fragments` and `Topology.counts()`: K is one past the highest fragment id (ids with no particle
left below it still count: a split's ids are never reused), an empty topology has K = 0 (not −1, so loops over
range(K) and `K > 2` tests stay empty), and `counts()` adds the fragment count only past two fragments."""

import torch

from fracture_gs.sim.topology import Topology


def _topo(fragment, band):
    return Topology(
        fragment=torch.tensor(fragment, dtype=torch.int32),
        band=torch.tensor(band, dtype=torch.int32),
        normal=(0.0, 0.0, 1.0),
        point=(0.0, 0.0, 0.0),
    )


def test_an_empty_topology_has_no_fragments():
    """No particles: K = 0 exactly, and the counts are all zero without a `fragments` entry."""
    t = _topo([], [])
    assert t.n_fragments == 0
    assert list(range(t.n_fragments)) == []
    assert t.counts() == {"fragment0": 0, "fragment1": 0, "band": 0}


def test_fragment_count_is_one_past_the_highest_id_gaps_included():
    """Ids {0, 3, 1}: K = 4 (id 2 has no particle but is a fragment id of the run); counts list fragments 0 and 1,
    the band (non-zero γ, any event index) and K = 4. Two fragments: K = 2 and no `fragments` entry; one fragment
    (all id 0): K = 1."""
    t = _topo([0, 3, 1, 3, 0], [0, 2, 1, 0, 0])
    assert t.n_fragments == 4
    assert t.counts() == {"fragment0": 2, "fragment1": 1, "band": 2, "fragments": 4}
    three = _topo([0, 2, 1], [0, 0, 0])
    assert three.n_fragments == 3 and three.counts()["fragments"] == 3
    two = _topo([1, 0, 1], [1, 0, 0])
    assert two.n_fragments == 2 and two.counts() == {"fragment0": 1, "fragment1": 2, "band": 1}
    assert _topo([0, 0], [0, 0]).n_fragments == 1
