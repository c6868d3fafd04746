"""`sim/providers/cuts.py` `plane_cut` over several fragments at once: each fragment is decided on its own, so a
fragment the plane misses (all its particles on one side) or one that finds no free id (`max_fragments`) does
not stop the fragments after it from being cut, or from growing their band; new ids are handed out in the
order the fragments are visited, from one past the largest id in use."""

import torch

from fracture_gs.sim.providers.cuts import plane_cut


def _x(*xs):
    return torch.tensor([[v, 0.0, 0.0] for v in xs])


def _i(*v):
    return torch.tensor(v, dtype=torch.int32)


def test_a_fragment_on_one_side_does_not_stop_the_fragments_after_it():
    """Plane x = 1 (normal +x), band width 0.25: fragment 0 lies wholly behind it, fragments 1 and 2 straddle
    it. Both are cut (positive sides take ids 3 and 4, in visiting order) and both grow a band; fragment 0 keeps
    its id and has no band. The same with the fragments listed as targets in that order."""
    x = _x(0.0, 0.5, 0.875, 1.125, 0.75, 1.5)
    fragment = _i(0, 0, 1, 1, 2, 2)
    band = _i(0, 0, 0, 0, 0, 0)
    for targets in (None, [0, 1, 2]):
        f, b, parents, children = plane_cut(x, fragment, band, (1, 0, 0), (1, 0, 0), 0.25, 8, targets, tag=3)
        assert f.tolist() == [0, 0, 1, 3, 2, 4], targets
        assert b.tolist() == [0, 0, 3, 3, 0, 0], targets  # 0.75 and 1.5 are 0.25, 0.5 away: not closer than 0.25
        assert (parents, children) == ([1, 2], [3, 4]), targets


def test_fragments_without_a_free_id_still_grow_their_band():
    """Ids 0-2 in use and max_fragments = 4: fragment 0 (listed first) straddles and takes id 3, fragments 1 and
    2 straddle too but find no free id: they keep their particles' ids, yet both still get their band."""
    x = _x(0.875, 1.125, 0.9, 1.1, 0.95, 1.05)
    fragment = _i(0, 0, 1, 1, 2, 2)
    f, b, parents, children = plane_cut(x, fragment, _i(0, 0, 0, 0, 0, 0), (1, 0, 0), (1, 0, 0), 0.25, 4, tag=1)
    assert f.tolist() == [0, 3, 1, 1, 2, 2]
    assert b.tolist() == [1, 1, 1, 1, 1, 1]
    assert (parents, children) == ([0], [3])
