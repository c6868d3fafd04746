"""`sim/diagnostics.py`'s plane-collider row (`Diagnostics._plane_row`) on a stand-in tracker fed hand-made frame
numbers: the first contact time of each fragment is the time of its first touching frame and is never
overwritten, penetration is the deepest so far in Δx, the post-contact normal speed counts only once something
touched, and the momentum residual is |p − (p₀ + M g t)| / (M |g| t): the momentum's departure from what
gravity alone gives a body of mass M after the elapsed time t (0 for free fall, 1 for a body held still)."""

import math
import types

import pytest
import torch

from fracture_gs.sim.diagnostics.tracker import Diagnostics

G = (0.0, -3.0, -4.0)  # |g| = 5 m/s²
M = 2.5  # kg
DX = 0.25


def _tracker(t0=0.5, p0=(1.0, 2.0, -1.0)):
    sim = types.SimpleNamespace(time=t0, cfg=types.SimpleNamespace(gravity=G), grid=types.SimpleNamespace(dx=DX))
    return types.SimpleNamespace(
        sim=sim,
        t0=t0,
        M=M,
        P0=torch.tensor(p0, dtype=torch.float64),
        plane_stats={"first_contact": [None, None], "penetration": 0.0, "max_vt_near": 0.0, "max_vn_post": 0.0},
    )


def _frame(d, time, touch=(0.0, 0.0), pen=0.0, vt=0.0, vn=0.0, momentum=(0.0, 0.0, 0.0)):
    d.sim.time = time
    h = {
        "plane_touch": list(touch),
        "plane_penetration": [pen],
        "plane_vt_near": [vt],
        "plane_vn_close": [vn],
        "momentum": list(momentum),
    }
    return Diagnostics._plane_row(d, h)


def _falling(p0, t):
    return [p0[i] + M * G[i] * t for i in range(3)]


def test_momentum_residual_measures_the_departure_from_free_fall():
    """Elapsed t = 1.5 s (t₀ = 0.5 s): a body whose momentum is p₀ + M g t reads 0; one that kept p₀ (held by
    the plane) reads exactly 1; one with an extra (0, 0, M|g|t/2) reads 0.5. At the start (t = t₀) the scale
    is 0 and the residual reads 0."""
    p0 = (1.0, 2.0, -1.0)
    d = _tracker(0.5, p0)
    assert _frame(d, 0.5, momentum=(7.0, 7.0, 7.0))["plane_momentum_residual"] == 0.0
    assert _frame(d, 2.0, momentum=_falling(p0, 1.5))["plane_momentum_residual"] == pytest.approx(0.0, abs=1e-15)
    assert _frame(d, 2.0, momentum=p0)["plane_momentum_residual"] == pytest.approx(1.0, rel=1e-12)
    half = _falling(p0, 1.5)
    half[2] += 0.5 * M * 5.0 * 1.5
    assert _frame(d, 2.0, momentum=half)["plane_momentum_residual"] == pytest.approx(0.5, rel=1e-12)
    t = 0.25  # another elapsed time: still 0 for free fall
    assert _frame(d, 0.5 + t, momentum=_falling(p0, t))["plane_momentum_residual"] == pytest.approx(0.0, abs=1e-15)


def test_first_contact_is_kept_and_the_maxima_only_grow():
    """Frame at 0.6 s: nothing touches (no contact time; a normal speed before contact is not counted).
    0.7 s: fragment 1 touches (its first contact 0.7). 0.8 s: both touch (fragment 0 first at 0.8, fragment 1
    stays 0.7). Penetration in Δx and the speeds keep their largest value so far."""
    d = _tracker()
    r = _frame(d, 0.6, pen=0.05, vt=0.3, vn=9.0)
    assert r["plane_first_contact"] == [None, None]
    assert r["plane_penetration"] == pytest.approx(0.2) and r["plane_max_vt_near"] == 0.3
    assert r["plane_max_vn_post"] == 0.0
    r = _frame(d, 0.7, touch=(0.0, 1.0), pen=0.125, vt=0.1, vn=2.0)
    assert r["plane_first_contact"] == [None, 0.7]
    assert r["plane_penetration"] == 0.5 and r["plane_max_vt_near"] == 0.3 and r["plane_max_vn_post"] == 2.0
    r = _frame(d, 0.8, touch=(3.0, 1.0), pen=0.0, vt=0.4, vn=1.0)
    assert r["plane_first_contact"] == [0.8, 0.7]
    assert r["plane_penetration"] == 0.5 and r["plane_max_vt_near"] == 0.4 and r["plane_max_vn_post"] == 2.0
    assert math.isfinite(r["plane_momentum_residual"])
