"""The tracker's contact rows (`Diagnostics._contact_row`, `_pair_row`) on a stand-in tracker fed hand-made
statistics, as the grid kernels accumulate them each frame.

Frame row: contact_nodes = gated nodes this frame; first_contact_time = the first frame's first-contact time
below NEVER, kept from then on; over frames with gated nodes, the running maxima of the contact-projection
momentum residual |Σ Δp| / max(Σ|p|, 1e-30), of the relative normal velocity after and of the largest tangential
velocity change (frames without gated nodes leave them). Pair row "a-b" (row-major over the K × K block read):
only pairs with gated nodes, each with its own first contact time, residual and node count; the surface
penetration of a behind b or b behind a goes under "min-max", the deeper of the two."""

import types

import pytest

from fracture_gs.sim.diagnostics.tracker import Diagnostics
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
    STAT_UN_AFTER,
)


def _tracker(pair_penetration=None):
    d = types.SimpleNamespace(
        first_contact_time=None,
        contact_max={"cp_momentum_residual": 0.0, "rel_normal_velocity_after": 0.0, "max_delta_vt": 0.0},
        pair_penetration=dict(pair_penetration or {}),
    )
    d._pair_row = lambda flat: Diagnostics._pair_row(d, flat)
    return d


def _stats(gated=0.0, first=NEVER, dp=(0.0, 0.0, 0.0), pnorm=0.0, un=0.0, dvt=0.0) -> list:
    s = [0.0] * N_STATS
    s[STAT_GATED], s[STAT_FIRST_T], s[STAT_PNORM], s[STAT_UN_AFTER], s[STAT_DVT] = gated, first, pnorm, un, dvt
    s[STAT_DPX], s[STAT_DPY], s[STAT_DPZ] = dp
    return s


def _pairs(K: int, rows: dict) -> list:
    """A flat K × K block of pair statistics with `rows` {(a, b): (first, dp, pnorm, gated)}."""
    flat = [0.0] * (K * K * N_PAIR_STATS)
    for (a, b), (first, dp, pnorm, gated) in rows.items():
        r = (a * K + b) * N_PAIR_STATS
        flat[r + PAIR_FIRST_T], flat[r + PAIR_PNORM], flat[r + PAIR_GATED] = first, pnorm, gated
        flat[r + PAIR_DPX], flat[r + PAIR_DPY], flat[r + PAIR_DPZ] = dp
    return flat


def _row(d, stats, pairs=None):
    return Diagnostics._contact_row(d, {"stats": stats, "pair_stats": pairs if pairs is not None else _pairs(2, {})})


def test_first_contact_is_kept_and_maxima_run_over_frames_with_contact():
    """Frame 1: no contact (first time NEVER): nothing set. Frame 2: 5 gated nodes first touching at 0.25 s,
    Σ Δp = (3, 0, 4) over Σ|p| = 10 (residual 0.5), u_n after 0.2, Δv_t 0.1. Frame 3: an earlier-looking first time
    0.125 does not replace 0.25; residual 0 and smaller speeds leave the maxima. Frame 4: no gated node, but large
    numbers in the other slots: ignored."""
    d = _tracker()
    r1 = _row(d, _stats())
    assert r1["contact_nodes"] == 0.0 and r1["first_contact_time"] is None
    assert (r1["cp_momentum_residual"], r1["rel_normal_velocity_after"], r1["max_delta_vt"]) == (0.0, 0.0, 0.0)
    r2 = _row(d, _stats(5.0, 0.25, (3.0, 0.0, 4.0), 10.0, 0.2, 0.1))
    assert r2["contact_nodes"] == 5.0 and r2["first_contact_time"] == 0.25
    assert r2["cp_momentum_residual"] == pytest.approx(0.5, rel=1e-15)
    assert (r2["rel_normal_velocity_after"], r2["max_delta_vt"]) == (0.2, 0.1)
    r3 = _row(d, _stats(2.0, 0.125, (0.0, 0.0, 0.0), 10.0, 0.05, 0.01))
    assert r3["first_contact_time"] == 0.25 and r3["cp_momentum_residual"] == pytest.approx(0.5, rel=1e-15)
    assert (r3["rel_normal_velocity_after"], r3["max_delta_vt"]) == (0.2, 0.1)
    r4 = _row(d, _stats(0.0, NEVER, (100.0, 0.0, 0.0), 1.0, 9.0, 9.0))
    assert r4["contact_nodes"] == 0.0 and r4["cp_momentum_residual"] == pytest.approx(0.5, rel=1e-15)
    assert (r4["rel_normal_velocity_after"], r4["max_delta_vt"]) == (0.2, 0.1)


def test_a_zero_momentum_norm_does_not_divide_by_zero():
    """Gated nodes with Σ|p| = 0 and Σ Δp = (0, 0, 2e-30): residual 2e-30 / 1e-30 = 2, finite."""
    d = _tracker()
    assert _row(d, _stats(1.0, 0.5, (0.0, 0.0, 2e-30), 0.0))["cp_momentum_residual"] == pytest.approx(2.0)


def test_pair_rows_decode_the_block_row_major_and_skip_untouched_pairs():
    """K = 3: pair (1, 2) gated 4 nodes from 0.5 s, Σ Δp = (1, 2, 2) over Σ|p| = 6 (residual 0.5); pair (2, 0) one node
    from 0.75 s with no momentum (residual 0); pair (0, 1) has numbers but no gated node: left out."""
    rows = {
        (1, 2): (0.5, (1.0, 2.0, 2.0), 6.0, 4.0),
        (2, 0): (0.75, (0.0, 0.0, 0.0), 0.0, 1.0),
        (0, 1): (0.25, (5.0, 0.0, 0.0), 1.0, 0.0),
    }
    out = Diagnostics._pair_row(_tracker(), _pairs(3, rows))
    assert out.keys() == {"1-2", "2-0"}
    assert out["1-2"]["first_contact_time"] == 0.5 and out["1-2"]["contact_nodes"] == 4.0
    assert out["1-2"]["cp_momentum_residual"] == pytest.approx(0.5, rel=1e-15)
    assert out["2-0"] == {"first_contact_time": 0.75, "cp_momentum_residual": 0.0, "contact_nodes": 1.0}


def test_surface_penetration_goes_under_the_ordered_pair_name_the_deeper_way_round():
    """Depths (in Δx) of 0 behind 2 (0.5) and 2 behind 0 (0.3) both go under "0-2", which reads the deeper 0.5;
    a pair that only overlapped (no contact statistics) appears with its penetration alone; one that touched keeps
    its contact numbers beside it."""
    rows = {(0, 1): (0.5, (0.0, 0.0, 0.0), 1.0, 2.0)}
    d = _tracker({(0, 2): 0.5, (2, 0): 0.3, (1, 0): 0.125})  # the deeper first: a later, shallower one must not win
    out = Diagnostics._pair_row(d, _pairs(3, rows))
    assert out["0-2"] == {"penetration": 0.5}
    assert out["0-1"]["penetration"] == 0.125 and out["0-1"]["contact_nodes"] == 2.0
    assert out.keys() == {"0-1", "0-2"}
