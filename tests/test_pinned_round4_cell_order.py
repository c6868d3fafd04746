"""`sim/neighbourhood.cell_order` in `interleaved` mode against its definition, written out by hand: group the
particles by their cell key (row-major cell index, times the fragment count plus the fragment id after a
latch), keep each group in input order, then visit the groups in ascending key order once per round, taking
the k-th particle of every group that has one in round k. The definition holds wherever the particles are,
below the grid's origin too (negative cell indices), and for no particles at all."""

import random

import pytest
import torch

from fracture_gs.sim.neighbourhood import cell_order

SHAPE = (3, 4, 5)


def _by_definition(cells, fragment=None):
    """The interleaved order of particles with integer cells [(i, j, l), ...] (and fragment ids)."""
    keys = [(i * SHAPE[1] + j) * SHAPE[2] + l for i, j, l in cells]
    if fragment is not None:
        kf = max(fragment) + 1
        keys = [k * kf + f for k, f in zip(keys, fragment)]
    groups = {}
    for p, k in enumerate(keys):
        groups.setdefault(k, []).append(p)
    rounds = max(len(g) for g in groups.values())
    return [g[r] for r in range(rounds) for k, g in sorted(groups.items()) if r < len(g)]


def _particles(cells, rng):
    """One particle per entry, at a random point well inside its unit cell (no rounding at a cell face)."""
    x = [[c + 0.2 + 0.6 * rng.random() for c in cell] for cell in cells]
    return torch.tensor(x, dtype=torch.float32)


@pytest.mark.parametrize("with_fragments", [False, True])
def test_interleaved_rounds_follow_the_definition_below_the_origin_too(with_fragments):
    """200 particles in cells from −2 to 5 per axis (a third of them below the origin on some axis, some past the
    grid's upper end), with and without three fragments: cell_order equals the round-by-round definition."""
    rng = random.Random(7)
    cells = [tuple(rng.randint(-2, 5) for _ in range(3)) for _ in range(200)]
    assert any(min(c) < 0 for c in cells) and len(set(cells)) < len(cells), "negative cells and shared cells"
    x = _particles(cells, rng)
    fragment = [rng.randint(0, 2) for _ in cells] if with_fragments else None
    f = None if fragment is None else torch.tensor(fragment, dtype=torch.int32)
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, SHAPE, "interleaved", f)
    assert order.tolist() == _by_definition(cells, fragment)


def test_a_second_particle_below_the_origin_waits_for_the_next_round():
    """Two particles in cell z = −1 and one in cell z = 0 of a column: round 0 visits cell −1 then cell 0, the
    second particle of cell −1 comes last (a key shifted by the lowest key, not read as an absolute one that
    ties with cell 0's first particle)."""
    x = torch.tensor([[0.5, 0.5, -0.5], [0.5, 0.5, -0.6], [0.5, 0.5, 0.5]])
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "interleaved")
    assert order.tolist() == [0, 2, 1]


def test_no_particles_give_an_empty_order_in_both_modes():
    """An empty particle set has the empty permutation, in `interleaved` as in `cell` mode."""
    for mode in ("interleaved", "cell"):
        order = cell_order(torch.zeros(0, 3), (0.0, 0.0, 0.0), 1.0, SHAPE, mode)
        assert order.dtype == torch.int64 and order.numel() == 0
