"""`penetration.surface_penetration`: the per-particle surface depths summed up for a frame.

It reports the deepest depth, how many particles lie deeper than `crossing_at` (strictly), the deepest depth of
each ordered pair (a behind b's surface) and the kernel radius; a calibration that lacks a fragment id present is
made again from the positions. The scene: particle 0 of piece 0 and one particle of piece 1 a spacing apart, a
few other particles of piece 1 farther off; with a tiny filled density each of the two close particles fills
the other's ball, so both read the same depth, R·u with u the bisection's answer for a full ball."""

import pytest
import torch

from fracture_gs.sim.diagnostics import penetration as pen

R = 0.06


def _scene():
    """Particle 0 (piece 0) at the origin, piece 1 two spacings away on the axes, and one piece-1 particle (last)
    one spacing from particle 0."""
    rows = [(0.0, 0.0, 0.0, 0)]
    for a in range(3):
        for sign in (1.0, -1.0):
            p = [0.0, 0.0, 0.0]
            p[a] = 0.02 * sign
            rows.append((*p, 1))
    rows.append((0.0, 0.006, 0.008, 1))
    t = torch.tensor(rows, dtype=torch.float64)
    return t[:, :3].contiguous(), t[:, 3].long()


def _calibration(k: int = 2):
    return {"radius": R, "filled": torch.full((k,), 1e-3, dtype=torch.float64), "spacing": R / pen.SPACINGS}


def test_the_summary_names_both_pairs_and_counts_strictly_deeper_particles():
    """Both close particles read the full-ball depth d ≈ R: depth d, pairs (0, 1) and (1, 0) at d, the radius R;
    2 crossings at crossing_at = 0 and just below d, none at d itself (deeper than, not as deep as)."""
    x, frag = _scene()
    d = float(R * pen.depth_from_fraction(torch.tensor([1.0], dtype=torch.float64)))
    got = pen.surface_penetration(x, frag, 0.0, _calibration())
    assert got["depth"] == pytest.approx(d, rel=1e-9) and got["radius"] == R and got["crossing"] == 2
    assert got["pairs"].keys() == {(0, 1), (1, 0)}
    assert all(v == pytest.approx(d, rel=1e-9) for v in got["pairs"].values())
    depth = got["depth"]
    assert pen.surface_penetration(x, frag, depth * (1 - 1e-9), _calibration())["crossing"] == 2
    assert pen.surface_penetration(x, frag, depth, _calibration())["crossing"] == 0


def test_pieces_apart_read_an_empty_summary():
    """Move piece 1 far away: no depth, no crossing, no pair (the radius still reported)."""
    x, frag = _scene()
    x[frag == 1] += 1.0
    got = pen.surface_penetration(x, frag, 0.0, _calibration())
    assert got == {"depth": 0.0, "crossing": 0, "pairs": {}, "radius": R}


def test_a_calibration_short_of_a_fragment_id_is_made_again():
    """A calibration with one filled density for two pieces is replaced by one made from the positions (its
    radius, SPACINGS spacings of this scene, is not the given R); a complete one is used as given."""
    x, frag = _scene()
    assert pen.surface_penetration(x, frag, 0.0, _calibration(2))["radius"] == R
    fresh = pen.calibrate(x, frag)["radius"]
    assert fresh != R and pen.surface_penetration(x, frag, 0.0, _calibration(1))["radius"] == fresh
