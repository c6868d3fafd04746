"""One gated pair of fields at a node (`sim.physics.contact.contact_pair`), field 0 the lower fragment id: the
projection and the contact statistics the diagnostics read, against hand values.

Fragment 0 (m = 1 kg, v = 0) and fragment 1 (m = 3 kg, v = (0.5, 0, −1)) m/s, normal +z: u_n = −1 m/s, so they
approach. With restitution e = 0.5 the normal impulse is J = (1 + e)·1 / (1/1 + 1/3) = 1.125 N·s; Coulomb
friction μ = 0.1 then removes μJ = 0.1125 of the tangential slip's impulse (less than the 0.375 that would stop
it): w₀ = (0.1125, 0, −1.125), w₁ = (0.4625, 0, −0.625). The statistics of a gated pair: a count, the projected
count (only when projecting), the first contact time, the momentum change (0: the impulses are equal and opposite)
and |m₀v₀ + m₁v₁| = √11.25 it is measured against, the residual approach speed max(0, −(w₁ − w₀)·n), the change
of tangential relative velocity (0.5 → 0.35: 0.15); per fragment pair (row 0·K + 1) the same count, time and
momentum. Separating fields get nothing and record nothing; a pair whose higher id has no row (≥ K) counts in the
totals only."""

import pytest
import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.contact import (
    N_PAIR_STATS,
    N_STATS,
    NEVER,
    PAIR_DPX,
    PAIR_DPZ,
    PAIR_FIRST_T,
    PAIR_GATED,
    PAIR_PNORM,
    STAT_DPX,
    STAT_DPZ,
    STAT_DVT,
    STAT_FIRST_T,
    STAT_GATED,
    STAT_PNORM,
    STAT_PROJECTED,
    STAT_UN_AFTER,
    contact_pair,
)

ensure_warp()

V1 = (0.5, 0.0, -1.0)
T = 0.25
NEVER32 = float(torch.tensor(NEVER))  # "no contact yet" as the float32 statistics hold it


@wp.kernel
def _pair(
    v1: wp.vec3,
    project: int,
    record: int,
    frag1: int,
    stats: wp.array(dtype=float),
    pair_stats: wp.array(dtype=float),
    out: wp.array(dtype=wp.vec3),
):
    w0, w1 = contact_pair(
        wp.vec3(0.0), v1, 1.0, 3.0, wp.vec3(0.0, 0.0, 1.0), 0.5, 0.1, project, record, stats, pair_stats, 0, frag1,
        2, 0.25,
    )  # fmt: skip
    out[0] = w0
    out[1] = w1


def _run(v1=V1, project=1, record=1, frag1=1):
    """(w₀, w₁, stats [N_STATS], pair rows [4, N_PAIR_STATS]) after one pair, fragments 0 and frag1, K = 2."""
    stats = torch.zeros(N_STATS)
    stats[STAT_FIRST_T] = NEVER
    pairs = torch.zeros(4, N_PAIR_STATS)
    pairs[:, PAIR_FIRST_T] = NEVER
    out = wp.zeros(2, dtype=wp.vec3, device="cpu")
    inputs = [wp.vec3(*v1), project, record, frag1, wp.from_torch(stats), wp.from_torch(pairs.view(-1)), out]
    wp.launch(_pair, dim=1, inputs=inputs, device="cpu")
    w = out.numpy().tolist()
    return w[0], w[1], stats.double(), pairs.double()


def test_an_approaching_pair_is_projected_with_restitution_and_capped_friction():
    """w₀ = (0.1125, 0, −1.125), w₁ = (0.4625, 0, −0.625): normal relative speed +e = 0.5, slip 0.35."""
    w0, w1, _, _ = _run()
    assert w0 == pytest.approx([0.1125, 0.0, -1.125], abs=1e-6)
    assert w1 == pytest.approx([0.4625, 0.0, -0.625], abs=1e-6)


def test_a_projected_pair_records_its_count_time_momentum_and_residuals():
    """Totals: gated 1, projected 1, first time 0.25 s, Δp = 0, |p| = √11.25, residual approach 0, Δv_t 0.15; pair
    row 1 (fragments 0, 1): first time 0.25 s, Δp = 0, |p| = √11.25, gated 1; the other rows untouched."""
    _, _, s, pairs = _run()
    assert (s[STAT_GATED], s[STAT_PROJECTED], s[STAT_FIRST_T]) == (1.0, 1.0, T)
    assert float(s[STAT_DPX : STAT_DPZ + 1].abs().max()) < 1e-6
    assert float(s[STAT_PNORM]) == pytest.approx(11.25**0.5, rel=1e-6)
    assert float(s[STAT_UN_AFTER]) == 0.0
    assert float(s[STAT_DVT]) == pytest.approx(0.15, abs=1e-6)
    row = pairs[1]
    assert (row[PAIR_FIRST_T], row[PAIR_GATED]) == (T, 1.0)
    assert float(row[PAIR_DPX : PAIR_DPZ + 1].abs().max()) < 1e-6
    assert float(row[PAIR_PNORM]) == pytest.approx(11.25**0.5, rel=1e-6)
    for r in (0, 2, 3):
        assert pairs[r].tolist() == [NEVER32] + [0.0] * (N_PAIR_STATS - 1), r


def test_recording_without_projecting_measures_the_untouched_approach():
    """project = 0: velocities unchanged, gated 1 but projected 0, the residual approach speed the full 1 m/s, no
    change of tangential velocity."""
    w0, w1, s, _ = _run(project=0)
    assert w0 == [0.0, 0.0, 0.0] and w1 == list(V1)
    assert (s[STAT_GATED], s[STAT_PROJECTED], s[STAT_UN_AFTER], s[STAT_DVT]) == (1.0, 0.0, 1.0, 0.0)


@pytest.mark.parametrize("v1", [(0.5, 0.0, 1.0), (0.5, 0.0, 0.0)])
def test_separating_or_sliding_fields_get_nothing_and_record_nothing(v1):
    """v₁ = (0.5, 0, +1) (separating) or (0.5, 0, 0) (sliding, u_n = 0): velocities unchanged, every statistic as
    initialized — a pair that does not approach is not in contact."""
    w0, w1, s, pairs = _run(v1=v1)
    assert w0 == [0.0, 0.0, 0.0] and w1 == list(v1)
    assert s.tolist() == [0.0] * STAT_FIRST_T + [NEVER32] + [0.0] * (N_STATS - STAT_FIRST_T - 1)
    assert bool((pairs[:, PAIR_FIRST_T] == NEVER32).all()) and not bool(pairs[:, PAIR_FIRST_T + 1 :].any())


def test_a_pair_beyond_the_pair_rows_counts_in_the_totals_only():
    """Fragment 1's partner id 2 ≥ K = 2: totals count the pair; no pair row changes. record = 0: nothing at all,
    though the projection still acts."""
    _, _, s, pairs = _run(frag1=2)
    assert s[STAT_GATED] == 1.0
    assert bool((pairs[:, PAIR_FIRST_T] == NEVER32).all()) and not bool(pairs[:, PAIR_FIRST_T + 1 :].any())
    w0, _, s, _ = _run(record=0)
    assert w0 == pytest.approx([0.1125, 0.0, -1.125], abs=1e-6)
    assert s[STAT_GATED] == 0.0 and s[STAT_FIRST_T] == NEVER32
