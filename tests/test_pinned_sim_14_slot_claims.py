"""The slot storage's readers (`sim.grid.fields.Grid` and its two launches in `field_metrics_kernels`) count a
slot by its claim, never by what happens to lie in it:

- a pool slot with no owner (−1) belongs to no field: whatever its (p, m) or band entry hold, it adds nothing to
  the total mass, the fragment masses, the mixing, the shared-support count or the band mass;
- a slot claimed by a fragment id ≥ K (the `K` asked for) is a real field: it counts in the total, the mixing
  and the shared support, but in no per-fragment array of length K (no out-of-range index);
- slot 0 of a node without a claim (what a solo particle leaves: it deposits without claiming) counts in the
  total and makes its node active, but belongs to no fragment, is never "shared", and its band belongs to no
  field;
- a node whose slot 0 is empty but whose pool slot holds an active field is active (counted once), not shared;
- a field holding exactly ε_m is inactive (in slot 0 or a pool slot): its mass counts, its node is not made active
  or shared by it.

A 5³ grid, 3 slots, two fields written by hand (`simutil.fill_slots`) plus three special nodes; every number
below is a hand sum. The torch twins (`mass`, `band_mass`, `fragment_mass`, `mixing`) and the launches
(`field_sums`) must give the same."""

import pytest
import torch
from simutil import fill_slots

from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import EMPTY_KEY, ROW_FLAG

S = 5
EPS = 2.0**-20  # ε_m, exact in float32: a field holding exactly ε_m is inactive
A, B, C, D, E = 100, 106, 112, 118, 124  # flat indices of (4, 0, 0), (4, 1, 1), (4, 2, 2), (4, 3, 3), (4, 4, 4)


def _row(g, n):
    return int(torch.nonzero(g.key == n).flatten()[0])


def _grid():
    """Field 0 (slot 0): m = 1, v = (1, 0, 0) at every node. Field 1 (pool slot 1): m = 2, v = (0, 1, 0) on the 25
    nodes i = 0 (present but empty elsewhere). Band mass = the field's mass. Then:
    A: pool slot 2 unowned, holding stale (p, m) = (3, 3, 3, 5) and band 7;
    B: pool slot 2 claimed by fragment 2 (= K), m = 4, v = (0, 0, 1), band 6;
    C: no claim and no row (a solo particle's deposit): slot 0 m = 1 as everywhere;
    D: a row, but slot 0 unclaimed, with band 9 in slot 0;
    E: slot 0 (fragment 0's) empty, field 1 holding m = 2 there;
    G: field 1 holding exactly ε_m beside slot 0's m = 1; H: slot 0 holding exactly ε_m, field 1 empty."""
    g = Grid((0.0, 0.0, 0.0), 1.0 / S, (S, S, S), "cpu", slots=3)
    g.ensure_pool(S**3)
    m = torch.zeros(2, S, S, S, dtype=torch.float64)
    m[0] = 1.0
    m[1, 0] = 2.0
    m[0, 4, 4, 4], m[1, 4, 4, 4] = 0.0, 2.0
    m[1, 4, 4, 3] = EPS
    m[0, 4, 3, 4] = EPS
    vel = torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], dtype=torch.float64)
    fill_slots(g, m, vel[:, None, None, None, :].expand(2, S, S, S, 3))
    n, s1 = g.n_nodes, g.slots - 1
    r = _row(g, A)
    assert int(g.pool_owner[r * s1 + 1]) == -1
    g._mp[n + r * s1 + 1] = torch.tensor([3.0, 3.0, 3.0, 5.0])
    g.band[r * g.slots + 2] = 7.0
    r = _row(g, B)
    g.pool_owner[r * s1 + 1] = 2
    g._mp[n + r * s1 + 1] = torch.tensor([0.0, 0.0, 4.0, 4.0])
    g.band[r * g.slots + 2] = 6.0
    r = _row(g, C)
    g.key[r] = EMPTY_KEY
    g._owner[C] = 0
    g.band[r * g.slots : (r + 1) * g.slots] = 0.0
    r = _row(g, D)
    g._owner[D] = ROW_FLAG
    g.band[r * g.slots] = 9.0
    g.n_fields = 2
    return g


TOTAL = 123 * 1.0 + 26 * 2.0 + 4.0 + 2 * EPS  # slot 0 but at E and H, field 1, B's fragment 2, G and H; not A
MIXING = 25 * (1.0 * 2.0 / 3.0) * 2.0 + (1.0 * 4.0 / 5.0) * 2.0  # m₀m₁/(m₀+m₁)‖v₀ − v₁‖² at i = 0 and at B
SHARED = 100.0 * 26 / 124  # i = 0 and B hold two active fields; every node but H at least one (E: field 1)


def test_the_launches_count_slots_by_their_claims():
    """field_sums: fragment masses (121 + ε_m for fragment 0: C and D unclaimed, E empty, H at ε_m; 52 + ε_m for
    fragment 1; B's fragment 2 left out), mixing over the total 179 + 2ε_m (A's stale mass nowhere), shared
    support 26 of the 124 active nodes (G's field at ε_m shares nothing, H's slot 0 at ε_m is not active)."""
    cf, shared, mass = _grid().field_sums(EPS, 2)
    assert mass.tolist() == pytest.approx([121.0 + EPS, 52.0 + EPS], rel=1e-12)
    assert float(shared) == pytest.approx(SHARED, rel=1e-12)
    assert float(cf) == pytest.approx(MIXING / TOTAL, rel=1e-6)


def test_the_torch_twins_count_slots_by_their_claims():
    """fragment_mass and mixing give the launches' hand values on the same slots."""
    g = _grid()
    assert g.fragment_mass(2).tolist() == pytest.approx([121.0 + EPS, 52.0 + EPS], rel=1e-12)
    cf, shared = g.mixing(EPS)
    assert float(shared) == pytest.approx(SHARED, rel=1e-12)
    assert float(cf) == pytest.approx(MIXING / TOTAL, rel=1e-6)


def test_logical_fields_hold_claimed_slots_of_fragments_below_k_only():
    """mass and band_mass [K = 2, X, Y, Z]: field 0 is 1 at every node but C and D (no claim: 0) and E (empty),
    field 1 is 2 at i = 0 and E and 0 elsewhere; A's stale slot, B's fragment 2 and D's unclaimed band 9 appear
    nowhere. momentum: field 0 carries (1, 0, 0) per kg wherever it is."""
    g = _grid()
    want = torch.zeros(2, S, S, S, dtype=torch.float64)
    want[0] = 1.0
    want[1, 0] = 2.0
    want[0, 4, 4, 4], want[1, 4, 4, 4] = 0.0, 2.0
    want[1, 4, 4, 3], want[0, 4, 3, 4] = EPS, EPS
    for n in (C, D):
        want[0].view(-1)[n] = 0.0
    assert torch.equal(g.mass.double(), want)
    band = want.clone()
    band[0].view(-1)[C] = 0.0
    assert torch.equal(g.band_mass.double(), band)
    assert torch.equal(g.momentum[0, 1, 2, 3].double(), torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64))
