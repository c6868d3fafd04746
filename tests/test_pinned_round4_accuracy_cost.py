"""`sweep.expansion.accuracy_cost`, the estimated seconds of an accuracy cell, against its formula worked by hand:

    seconds = 0.35 ms · substeps · (1 + particles / 200,000) + 10 ms · frames,
    substeps = duration · c / (CFL · Δx),  particles = 8 per cell over the body's volume,

with each case's duration, speed c (P-wave speed plus the body's own speed) and frames: the bar runs two
periods of 0.1 s at c = √(E/ρ) and records no frames; the spinning cube runs one turn T at the P-wave speed plus
its rim speed ω·a/2 and records no frames either (it is sampled inside its one loop); the re-contact case runs
its 40 frames of 5 ms, each frame costing 10 ms of checks. The P-wave speed is written here without Lamé
parameters, √(E(1 − ν) / (ρ(1 + ν)(1 − 2ν)))."""

from __future__ import annotations

import math

import pytest

from fracture_gs.paper import accuracy as A
from fracture_gs.sweep.expansion import accuracy_cost


def _p_wave(E, nu, rho):
    return math.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu)))


def _seconds(substeps, particles, frames):
    return 0.35e-3 * substeps * (1 + particles / 2e5) + 0.01 * frames


@pytest.mark.parametrize("cells, cfl", [(16, 0.4), (48, 0.25)])
def test_the_bar_runs_two_periods_at_the_bar_wave_speed_with_no_frames(cells, cfl):
    """Bar (E = 10 kPa, ρ = 100 kg/m³: c = 10 m/s): 0.2 s, a 0.5 × 0.0625² m³ body; at 16 cells and CFL 0.4 that
    is 80 substeps over 64 particles, 28.00896 ms."""
    B = A.BAR
    c = math.sqrt(B["E"] / B["rho"])
    substeps = B["periods"] * 0.1 * c * cells / cfl
    expected = _seconds(substeps, 8 * 0.5 * 0.0625**2 * cells**3, 0)
    assert accuracy_cost("bar", cells, cfl) == pytest.approx(expected, rel=1e-12)
    if (cells, cfl) == (16, 0.4):
        assert expected == pytest.approx(0.35e-3 * 80 * (1 + 64 / 2e5), rel=1e-12)


@pytest.mark.parametrize("cells, cfl", [(16, 0.4), (48, 0.25)])
def test_the_spinning_cube_runs_one_turn_at_wave_plus_rim_speed_with_no_frames(cells, cfl):
    """Spin (a = 0.2 m cube, ω = 5 rad/s, one turn T = 2π/5 s): c = P-wave speed + ω·a/2, a³ of body, and no
    per-frame cost at all (the cell is sampled inside its one loop)."""
    S = A.SPIN
    c = _p_wave(S["E"], S["nu"], S["rho"]) + S["omega"] * S["a"] / 2
    expected = _seconds(S["T"] * c * cells / cfl, 8 * S["a"] ** 3 * cells**3, 0)
    assert accuracy_cost("spin", cells, cfl) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("cells, cfl", [(16, 0.4), (48, 0.25)])
def test_recontact_runs_its_forty_frames_at_wave_plus_approach_speed(cells, cfl):
    """Re-contact (E = 200 kPa, ν = 0.3, ρ = 1000 kg/m³, pieces approaching at 0.6 m/s): 40 frames of 5 ms, a
    7.4e-4 m³ body, and 10 ms of checks per frame (0.4 s of the estimate)."""
    R = A.RECONTACT
    c = _p_wave(R["E"], 0.3, R["rho"]) + R["speed"]
    expected = _seconds(R["frames"] * R["frame_dt"] * c * cells / cfl, 8 * 7.4e-4 * cells**3, R["frames"])
    assert accuracy_cost("recontact", cells, cfl) == pytest.approx(expected, rel=1e-12)
    assert R["frames"] == 40 and R["frame_dt"] == 0.005
