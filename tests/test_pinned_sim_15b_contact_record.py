"""The contact statistics of one gated pair (`sim.physics.contact.record_contact`), for velocities after the pair
that need not conserve momentum — the statistics exist to show when they do not, so each axis must be recorded on
its own.

Pair: m₀ = 2 kg at v₀ = 0, m₁ = 1 kg at v₁ = (1, 0, −2) m/s, normal +z; afterwards w₀ = (0.5, 1, 0.5),
w₁ = (1.5, −0.25, −1). By hand: momentum before m₀v₀ + m₁v₁ = (1, 0, −2), |·| = √5; after (2.5, 1.75, 0), so the
momentum change is dp = (1.5, 1.75, 2); the residual approach speed max(0, −(w₁ − w₀)·n) = 1.5 m/s; the tangential
relative velocity goes from (1, 0, 0) to (1, −1.25, 0), a change of 1.25 m/s. Every gated pair adds 1 to the count
(and to the projected count only when it projected), the momentum change and |p| add up, the first time is the
earliest, the residual and the tangential change keep their maximum. The fragment pair's row (index `pair`, −1: no
row) gets the count, the first time, dp per axis and |p|."""

import math

import pytest
import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.contact import (
    N_PAIR_STATS,
    N_STATS,
    NEVER,
    PAIR_DPX,
    PAIR_DPY,
    PAIR_DPZ,
    PAIR_FIRST_T,
    PAIR_GATED,
    PAIR_PNORM,
    STAT_DPX,
    STAT_DPY,
    STAT_DPZ,
    STAT_DVT,
    STAT_FIRST_T,
    STAT_GATED,
    STAT_PNORM,
    STAT_PROJECTED,
    STAT_UN_AFTER,
    record_contact,
)

ensure_warp()


@wp.kernel
def _record(
    stats: wp.array(dtype=float), pair_stats: wp.array(dtype=float), pair: int, t: float, project: int, flip: int
):
    v0, v1 = wp.vec3(0.0), wp.vec3(1.0, 0.0, -2.0)
    w0, w1 = wp.vec3(0.5, 1.0, 0.5), wp.vec3(1.5, -0.25, -1.0)
    if flip != 0:  # a pair that separates after: the residual approach speed is 0
        w1 = wp.vec3(1.5, -0.25, 2.0)
    record_contact(stats, pair_stats, pair, t, v0, v1, w0, w1, 2.0, 1.0, wp.vec3(0.0, 0.0, 1.0), project)


def _fresh():
    stats = torch.zeros(N_STATS)
    stats[STAT_FIRST_T] = NEVER
    pairs = torch.zeros(3, N_PAIR_STATS)
    pairs[:, PAIR_FIRST_T] = NEVER
    return stats, pairs


def _launch(stats, pairs, pair, t, project=1, flip=0):
    inputs = [wp.from_torch(stats), wp.from_torch(pairs.view(-1)), pair, t, project, flip]
    wp.launch(_record, dim=1, inputs=inputs, device="cpu")


def test_one_pair_records_each_axis_of_its_momentum_change_and_its_residuals():
    """One projected pair in row 1: count 1, projected 1, dp = (1.5, 1.75, 2) in the totals and in the row, |p| = √5,
    residual approach 1.5 m/s, tangential change 1.25 m/s, first time 0.5 s; rows 0 and 2 untouched."""
    stats, pairs = _fresh()
    _launch(stats, pairs, 1, 0.5)
    s = stats.double()
    assert (s[STAT_GATED], s[STAT_PROJECTED], s[STAT_FIRST_T]) == (1.0, 1.0, 0.5)
    assert [float(s[i]) for i in (STAT_DPX, STAT_DPY, STAT_DPZ)] == [1.5, 1.75, 2.0]
    assert float(s[STAT_PNORM]) == pytest.approx(math.sqrt(5.0), rel=1e-6)
    assert float(s[STAT_UN_AFTER]) == pytest.approx(1.5, rel=1e-6)
    assert float(s[STAT_DVT]) == pytest.approx(1.25, rel=1e-6)
    row = pairs[1].double()
    assert (row[PAIR_FIRST_T], row[PAIR_GATED]) == (0.5, 1.0)
    assert [float(row[i]) for i in (PAIR_DPX, PAIR_DPY, PAIR_DPZ)] == [1.5, 1.75, 2.0]
    assert float(row[PAIR_PNORM]) == pytest.approx(math.sqrt(5.0), rel=1e-6)
    for r in (0, 2):
        assert pairs[r].tolist() == [float(torch.tensor(NEVER))] + [0.0] * (N_PAIR_STATS - 1)


def test_pairs_add_up_keep_the_earliest_time_and_the_largest_residuals():
    """Three pairs into row 2 at t = 0.5, 0.25 (recorded without projecting) and 0.75 s (separating after):
    count 3, projected 2, dp and |p| three times one pair's, first time 0.25 s, residual max(1.5, 1.5, 0) = 1.5,
    tangential change max = 1.25 (the separating pair's is 1.25 too); a pair with no row (−1) adds to the totals
    only."""
    stats, pairs = _fresh()
    _launch(stats, pairs, 2, 0.5)
    _launch(stats, pairs, 2, 0.25, project=0)
    _launch(stats, pairs, 2, 0.75, flip=1)
    s = stats.double()
    # the separating pair's w₁ = (1.5, −0.25, 2): after-momentum z = 1 + 2 = 3, dp_z = 5
    assert (s[STAT_GATED], s[STAT_PROJECTED], s[STAT_FIRST_T]) == (3.0, 2.0, 0.25)
    assert [float(s[i]) for i in (STAT_DPX, STAT_DPY, STAT_DPZ)] == [4.5, 5.25, 9.0]
    assert float(s[STAT_PNORM]) == pytest.approx(3 * math.sqrt(5.0), rel=1e-6)
    assert float(s[STAT_UN_AFTER]) == pytest.approx(1.5, rel=1e-6)
    assert float(s[STAT_DVT]) == pytest.approx(1.25, rel=1e-6)
    row = pairs[2].double()
    assert (row[PAIR_FIRST_T], row[PAIR_GATED]) == (0.25, 3.0)
    assert [float(row[i]) for i in (PAIR_DPX, PAIR_DPY, PAIR_DPZ)] == [4.5, 5.25, 9.0]
    before = pairs.clone()
    _launch(stats, pairs, -1, 0.125)
    assert torch.equal(pairs, before)
    assert (float(stats[STAT_GATED]), float(stats[STAT_FIRST_T]), float(stats[STAT_DPZ])) == (4.0, 0.125, 11.0)
