"""The building blocks of the surface measure's calibration (`penetration._group_median`, `_nearest`, `_sampled`).

_group_median: per group id 0…K−1 the lower middle of its sorted values and its count, 0 for an empty group.
_nearest: each query's distance to the nearest *other* particle of its own fragment in the 27 cells of edge `size`
around its own (so every one within `size`; inf if none): other fragments and the query itself never count.
_sampled: up to `samples` distinct particles of each fragment."""

import math

import torch

from fracture_gs.sim.diagnostics.penetration import _group_median, _nearest, _sampled


def test_group_median_is_the_lower_middle_and_zero_for_an_empty_group():
    """Group 0 holds 5, 1, 3, 7 (sorted 1 3 5 7: lower middle 3), group 1 nothing (0, count 0), group 2 holds 20,
    10 (lower middle 10), group 3 the single 4; odd counts take the true middle."""
    values = torch.tensor([5.0, 20.0, 1.0, 3.0, 10.0, 7.0, 4.0], dtype=torch.float64)
    groups = torch.tensor([0, 2, 0, 0, 2, 0, 3])
    med, count = _group_median(values, groups, 4)
    assert med.tolist() == [3.0, 0.0, 10.0, 4.0] and count.tolist() == [4, 0, 2, 1]
    med, count = _group_median(values[:5], groups[:5], 3)  # group 0: 1 3 5 (middle 3), group 2: 10 20 (10)
    assert med.tolist() == [3.0, 0.0, 10.0] and count.tolist() == [3, 0, 2]
    med, count = _group_median(torch.zeros(0, dtype=torch.float64), torch.zeros(0, dtype=torch.long), 2)
    assert med.tolist() == [0.0, 0.0] and count.tolist() == [0, 0]


def test_nearest_is_within_the_own_fragment_and_never_the_query_itself():
    """On a line, cells of edge `size`: fragment 0 at 0, 0.3 and 1.0, fragment 1 at 0.1 and 1.3. Particle 0's
    nearest own is 0.3 away (fragment 1's at 0.1 does not count, nor itself at 0); with size 0.5 particle 2's own
    (0.7 away) and fragment 1's pair (1.2 apart) lie two cells off: inf. With size 1 they are found: 0.7 and 1.2."""
    x = torch.tensor([[0.0, 0, 0], [0.3, 0, 0], [1.0, 0, 0], [0.1, 0, 0], [1.3, 0, 0]], dtype=torch.float64)
    frag = torch.tensor([0, 0, 0, 1, 1])
    got = _nearest(x, frag, torch.arange(5), 0.5).tolist()
    assert [round(v, 12) for v in got[:2]] == [0.3, 0.3] and all(math.isinf(v) for v in got[2:])
    wide = _nearest(x, frag, torch.tensor([2, 3, 4]), 1.0).tolist()
    assert [round(v, 12) for v in wide] == [0.7, 1.2, 1.2]


def test_sampled_takes_up_to_the_cap_of_each_fragment_distinct():
    """Fragment sizes 7, 2 and 0 (id 2 unused) and 4 for id 3, cap 3: 3 + 2 + 0 + 3 distinct indices, each of the
    fragment it is counted for; a cap above every size takes everything."""
    frag = torch.tensor([0, 1, 0, 3, 0, 0, 3, 1, 0, 3, 0, 3, 0])
    pick = _sampled(frag, 4, 3)
    assert len(set(pick.tolist())) == len(pick)
    assert torch.bincount(frag[pick], minlength=4).tolist() == [3, 2, 0, 3]
    assert sorted(_sampled(frag, 4, 100).tolist()) == list(range(len(frag)))
