"""Voronoi labels on exact ties (`sim.providers.cuts.voronoi_labels`).

Every particle takes the cell of its nearest seed, s₁, and is in the band when its distance to the bisector with its
second-nearest seed s₂, (|x − s₂|² − |x − s₁|²) / 2|s₂ − s₁|, is below the band width. A particle exactly as far
from two seeds (a lattice scene whose sites are its own particles has many) takes the seed listed first, for s₁ and
s₂ alike: a stated rule, the same on every torch version and device, where `topk`'s order of equal values is not
(asking it for the three nearest instead of two reordered the ties of about one particle in thirty). The labels are
checked against the rule written out by hand in exact integer arithmetic on integer lattices.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import pytest
import torch

from fracture_gs.sim.providers.cuts import voronoi_labels


def _by_hand(points, seeds, width):
    """The rule in exact arithmetic: s₁ = the first seed at the least squared distance, s₂ = the first of the others
    at their least; band when (d₂ − d₁)² < width² · 4|s₂ − s₁|² (both sides ≥ 0)."""
    cells, bands, margins = [], [], []
    for p in points:
        d = [sum((a - b) ** 2 for a, b in zip(p, s)) for s in seeds]
        i = min(range(len(seeds)), key=lambda j: (d[j], j))
        rest = [j for j in range(len(seeds)) if j != i]
        k = min(rest, key=lambda j: (d[j], j))
        norm2 = sum((a - b) ** 2 for a, b in zip(seeds[k], seeds[i]))
        lhs, rhs = Fraction(d[k] - d[i]) ** 2, width**2 * 4 * norm2
        cells.append(i)
        bands.append(int(lhs < rhs))
        margins.append(abs(lhs - rhs) / rhs)
    return cells, bands, min(margins)


@pytest.mark.parametrize("seed", range(6))
def test_labels_on_an_integer_lattice_follow_the_first_listed_seed_on_ties(seed):
    """216 particles on the integer points of [0, 6)³ and 3 … 8 distinct lattice points as seeds: every cell and
    band flag equals the hand-written rule (ties to the seed listed first, at both places), for a band width of
    0.7 (no particle within 1 % of it, so rounding cannot decide). The scenes have ties to decide."""
    g = torch.Generator().manual_seed(seed)
    points = list(itertools.product(range(6), repeat=3))
    m = 3 + seed
    seeds = [points[i] for i in torch.randperm(len(points), generator=g)[:m].tolist()]
    width = Fraction(7, 10)
    cells, bands, margin = _by_hand(points, seeds, width)
    assert margin > 0.01
    d = [[sum((a - b) ** 2 for a, b in zip(p, s)) for s in seeds] for p in points]
    assert sum(sorted(row)[0] == sorted(row)[1] for row in d) > 0, "some particle is equidistant from two seeds"
    x = torch.tensor(points, dtype=torch.float32)
    cell, band = voronoi_labels(x, torch.tensor(seeds, dtype=torch.float32), float(width))
    assert cell.dtype == torch.int32 and band.dtype == torch.int32
    assert cell.tolist() == cells
    assert band.tolist() == bands


def test_a_particle_between_two_seeds_takes_the_one_listed_first():
    """A particle at (1, 0, 0), 1 from seeds (0, 0, 0) and (2, 0, 0): with a far seed listed first, it takes
    index 1, whichever of the two near ones is listed there; it lies on their bisector (gap 0), so it is in the
    band for any positive width."""
    x = torch.tensor([[1.0, 0.0, 0.0]])
    far, a, b = [0.0, 9.0, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]
    for seeds in ([far, a, b], [far, b, a]):
        cell, band = voronoi_labels(x, torch.tensor(seeds), 1e-6)
        assert cell.tolist() == [1] and band.tolist() == [1], seeds


def test_a_second_place_tie_measures_the_band_to_the_first_listed_seeds_bisector():
    """A particle at the origin, nearest seed (1, 0, 0) (d² = 1), and two seeds tied behind it at d² = 4: to the
    bisector with (−2, 0, 0) the gap is (4 − 1)/(2·3) = 0.5, with (0, 2, 0) it is 3/(2√5) ≈ 0.671. With a band width
    of 0.6 the particle is in the band when (−2, 0, 0) is listed before (0, 2, 0), and not when it is listed after."""
    x = torch.tensor([[0.0, 0.0, 0.0]])
    near, left, up = [1.0, 0.0, 0.0], [-2.0, 0.0, 0.0], [0.0, 2.0, 0.0]
    cell, band = voronoi_labels(x, torch.tensor([near, left, up]), 0.6)
    assert cell.tolist() == [0] and band.tolist() == [1]
    cell, band = voronoi_labels(x, torch.tensor([near, up, left]), 0.6)
    assert cell.tolist() == [0] and band.tolist() == [0]


def test_labels_leave_the_callers_tensors_as_they_were():
    """The function works on its own distance table: particles and seeds passed in (float64, which it does not
    copy) are unchanged."""
    x = torch.tensor([[1.0, 0.0, 0.0], [0.2, 0.1, 0.0]], dtype=torch.float64)
    seeds = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0]], dtype=torch.float64)
    before = (x.clone(), seeds.clone())
    voronoi_labels(x, seeds, 0.5)
    assert torch.equal(x, before[0]) and torch.equal(seeds, before[1])
