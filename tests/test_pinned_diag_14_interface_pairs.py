"""The interface pairs the tracker builds at the first latch: each band particle of fragment 0 with its nearest
band particle of fragment 1 within `pair_radius`·Δx (the radius in cells, turned into metres by Δx), and the
opening's origin, their mean distance along n_Π.

Two lattices (spacing Δx/2) face each other across the plane x = ½ with their faces a chosen distance apart; every
particle's nearest partner is straight across, on the other face. With the faces 0.75Δx apart and pair_radius 1.5,
fragment 0's two front layers pair (0.75Δx and 1.25Δx away, the third is 1.75Δx away): opening0 = 1.0Δx. With the
faces 2Δx apart nothing pairs. Positions are exact binary fractions in float32."""

import pytest
import torch
from simutil import config, particles

from fracture_gs import sim as S

DX = 1.0 / 32
LAYERS, SIDE = 6, 8  # layers per block along x; particles per side across


def _facing(gap: float) -> torch.Tensor:  # [2·LAYERS·SIDE², 3] fragment 0 first (x < ½), faces `gap`·Δx apart
    k = torch.arange(LAYERS, dtype=torch.float64)
    lo = 0.5 - (gap / 2 + 0.5 * k) * DX
    hi = 0.5 + (gap / 2 + 0.5 * k) * DX
    yz = 0.4 + 0.5 * DX * torch.arange(SIDE, dtype=torch.float64)
    blocks = [torch.stack(torch.meshgrid(xs, yz, yz, indexing="ij"), -1).reshape(-1, 3) for xs in (lo, hi)]
    return torch.cat(blocks).float()


def _tracker(gap: float):
    x = _facing(gap)
    sim = S.Simulator(config(32), particles(x, (DX / 2) ** 3, E=1e4, nu=0.3), device="cpu")
    topo = S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 4 * DX, pair_radius=1.5)
    sim.latch(topo)
    return sim, sim.diagnostics_tracker()  # the tracker holds its simulator weakly: keep both


def test_front_layers_within_the_radius_in_cells_pair_and_set_the_opening_origin():
    """Faces 0.75Δx apart: fragment 0's two front layers pair (2·SIDE² pairs), and their mean distance along n_Π,
    the opening's origin, is (0.75 + 1.25)/2 = 1.0Δx."""
    _, d = _tracker(0.75)
    assert d.latch_info["interface_pairs"] == 2 * SIDE * SIDE
    assert d.opening0 == DX


def test_faces_farther_apart_than_the_radius_make_no_pairs():
    """Faces 2Δx apart (more than pair_radius = 1.5 cells), every particle in the band: no pair, opening origin 0."""
    _, d = _tracker(2.0)
    assert d.latch_info["interface_pairs"] == 0 and d.opening0 == 0.0


@pytest.mark.slow  # four tracker snapshots of a latched state: ≈ 3.5 s on a busy 2-core machine
def test_the_interface_row_follows_fragment_1_moved_by_known_distances():
    """Faces 0.75Δx apart at the latch, then fragment 1 moved along n_Π by +0.25Δx, −0.125Δx and −1Δx (in Δx):

    - opening = mean pair distance minus opening0: 0, 0.25, 0.125, −0.875; separated while it exceeds 0.1Δx;
    - reapproach = drop below the running maximum (0.25) over that maximum: 0, 0, 0.5, 4.5;
    - penetration: at −0.875 the front layers have passed each other by 0.125Δx, so the deepest neighbour lies
      0.125Δx behind; before that 0;
    - identity crossing: the plane midway between the passed fronts puts both front layers (SIDE² each) on the
      wrong side: 2·SIDE² particles; before that none."""
    sim, d = _tracker(0.75)
    x = sim.particles.x
    one = sim.particles.fragment == 1
    rows = [d.snapshot()]
    for shift in (0.25, -0.125, -1.0):
        with torch.no_grad():
            x[one, 0] += shift * DX
        rows.append(d.snapshot())
    got = {k: [r[k] for r in rows] for k in ("opening", "reapproach", "separated", "penetration", "identity_crossing")}
    assert got["opening"] == pytest.approx([0.0, 0.25, 0.125, -0.875], abs=1e-9)
    assert got["reapproach"] == pytest.approx([0.0, 0.0, 0.5, 4.5], abs=1e-9)
    assert got["separated"] == [False, True, True, False]
    assert got["penetration"] == pytest.approx([0.0, 0.0, 0.0, 0.125], abs=1e-9)
    assert got["identity_crossing"] == [0, 0, 0, 2 * SIDE * SIDE]
