"""Which particles the surface measure evaluates: only those with a particle of another labelled piece closer than
NEAR spacings (`penetration.surface_depth`, in Warp and in its torch twin).

A particle behind b's surface has a particle of b within about a spacing, so the measure evaluates only particles
with one of another piece (id ≥ 0) closer than NEAR·s. A particle whose nearest other-piece particles lie farther
reads depth 0 even where those particles would fill its kernel ball; its own piece's particles and unlabelled
ones (id −1) never make it a candidate. The Warp kernel's 27-cell walk finds exactly the pairs a brute-force
distance check finds."""

import pytest
import torch

from fracture_gs.sim.diagnostics import penetration as pen
from fracture_gs.sim.diagnostics import penetration_kernels as pk

R = 0.06  # kernel radius: spacing s = R / SPACINGS = 0.01, reach NEAR·s = 0.012


def _calibration():
    """A tiny filled density: any particle of b inside the ball fills it (share ≥ 1, depth ≈ R) once evaluated."""
    return {"radius": R, "filled": torch.full((3,), 1e-3, dtype=torch.float64), "spacing": R / pen.SPACINGS}


def _shell(extra=None):
    """Particle 0 of piece 0 at the origin; six particles of piece 1 two spacings away on the axes (beyond the
    reach, inside the ball); `extra` rows (x, y, z, id) appended."""
    rows = [(0.0, 0.0, 0.0, 0)]
    for a in range(3):
        for sign in (1.0, -1.0):
            p = [0.0, 0.0, 0.0]
            p[a] = 0.02 * sign
            rows.append((*p, 1))
    rows += extra or []
    t = torch.tensor(rows, dtype=torch.float64)
    return t[:, :3].contiguous(), t[:, 3].long()


@pytest.mark.parametrize("twin", [False, True])
def test_other_pieces_beyond_the_reach_leave_a_particle_unevaluated(twin):
    """Piece 1 two spacings around particle 0 (farther than NEAR·s = 1.2 s): no particle is evaluated, every depth
    is 0 and no piece is named — though piece 1 would fill particle 0's ball."""
    x, frag = _shell()
    depth, into = pen.surface_depth(x, frag, _calibration(), twin=twin)
    assert float(depth.abs().max()) == 0.0 and into.tolist() == [-1] * len(x)


@pytest.mark.parametrize("twin", [False, True])
def test_an_unlabelled_or_own_particle_within_reach_does_not_make_a_candidate(twin):
    """An unlabelled particle and a particle of piece 0 itself half a spacing from particle 0: still nothing is
    evaluated (neither is another labelled piece)."""
    x, frag = _shell([(0.005, 0.005, 0.0, -1), (-0.004, 0.0, 0.003, 0)])
    depth, into = pen.surface_depth(x, frag, _calibration(), twin=twin)
    assert float(depth.abs().max()) == 0.0 and into.tolist() == [-1] * len(x)


@pytest.mark.parametrize("twin", [False, True])
def test_another_piece_within_reach_makes_a_candidate_read_its_depth(twin):
    """One more particle of piece 1 one spacing from particle 0 (inside the reach): particle 0 is evaluated, lies
    behind piece 1 with its ball filled (depth within 1e-3 R of R), and that piece-1 particle behind piece 0."""
    x, frag = _shell([(0.0, 0.006, 0.008, 1)])
    depth, into = pen.surface_depth(x, frag, _calibration(), twin=twin)
    assert int(into[0]) == 1 and float(depth[0]) == pytest.approx(R, rel=1e-3)
    assert int(into[-1]) == 0 and float(depth[-1]) == pytest.approx(R, rel=1e-3)
    assert into[1:-1].tolist() == [-1] * 6 and float(depth[1:-1].abs().max()) == 0.0


def test_the_kernel_walk_finds_exactly_the_brute_force_pairs():
    """Random particles of three pieces and unlabelled ones in a small box: a query is near another piece exactly
    when a brute-force distance check finds a particle with id ≥ 0, another id, closer than the reach — in every
    direction of the 27 cells (the reach equals the cell edge)."""
    g = torch.Generator().manual_seed(1414)
    x = 0.1 * torch.rand(600, 3, dtype=torch.float64, generator=g)
    frag = torch.randint(-1, 3, (600,), generator=g)
    reach = 0.011
    cells = pen._Cells(x, frag, x.min(0).values, reach)
    query = torch.nonzero(frag >= 0).flatten()
    near = pk.near_another_piece_mask(x, frag, cells, query, reach, pen._BITS)
    d = torch.cdist(x[query], x)  # [M, N]
    other = (frag[None, :] >= 0) & (frag[None, :] != frag[query][:, None])
    expected = ((d < reach) & other).any(1)
    assert torch.equal(near, expected)
    assert 0.2 < float(expected.double().mean()) < 0.8, "the scene must have both near and lone queries"
