"""`sim/providers/cuts.py`, the label operations of fracture events, against hand-built scenes: which
side of a plane gets the new id, which particles join the band (and that a later cut never re-tags an
earlier band), the Voronoi band's distance to the bisector, and connected components (26-connected
cells, the largest piece keeps the id, `min_particles` and `max_fragments` bounds)."""

import torch

from fracture_gs.sim.providers.cuts import plane_cut, split_components, voronoi_labels


def _cells(lo, hi, per_cell=1):
    """Particles at the centres of the unit cells lo ≤ c < hi (per axis), `per_cell` copies each ([N, 3])."""
    axes = [torch.arange(a, b, dtype=torch.float32) + 0.5 for a, b in zip(lo, hi)]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return x.repeat_interleave(per_cell, 0)


def _zeros(x):
    return torch.zeros(len(x), dtype=torch.int32)


def test_split_components_the_largest_piece_keeps_the_parent_id():
    """Two disconnected pieces of fragment 0 (64 and 27 particles, the smaller listed first): the larger
    keeps id 0, the smaller takes the next free id."""
    small = _cells((0, 0, 0), (3, 3, 3))
    large = _cells((10, 0, 0), (14, 4, 4))
    x = torch.cat([small, large])
    out, parents, children = split_components(x, _zeros(x), 1.0, 64)
    assert parents == [0] and children == [1]
    assert bool((out[: len(small)] == 1).all()) and bool((out[len(small) :] == 0).all())


def test_split_components_corner_neighbour_cells_are_connected():
    """Connectivity is 26-neighbour: two blocks meeting only at a cell corner are one piece; a gap of one
    empty cell makes two."""
    a = _cells((0, 0, 0), (3, 3, 3))
    corner = torch.cat([a, _cells((3, 3, 3), (6, 6, 6))])
    out, parents, _ = split_components(corner, _zeros(corner), 1.0, 64)
    assert parents == [] and bool((out == 0).all())
    gap = torch.cat([a, _cells((4, 4, 4), (7, 7, 7))])
    out, parents, _ = split_components(gap, _zeros(gap), 1.0, 64)
    assert parents == [0] and set(out.tolist()) == {0, 1}


def test_split_components_min_particles_bounds_pieces_and_fragments():
    """A piece of exactly `min_particles` particles gets its own id, one particle fewer stays with its
    parent; a fragment with fewer than 2·min_particles particles is never split."""
    big = _cells((0, 0, 0), (3, 3, 3))  # 27
    for piece, split in ((8, True), (7, False)):
        x = torch.cat([big, _cells((10, 0, 0), (10 + piece, 1, 1))])
        out, parents, _ = split_components(x, _zeros(x), 1.0, 64, min_particles=8)
        assert (parents == [0]) is split, piece
        assert bool((out[27:] == (1 if split else 0)).all())
    tiny = torch.cat([_cells((0, 0, 0), (4, 2, 1)), _cells((10, 0, 0), (17, 1, 1))])  # 8 + 7 < 16
    _, parents, _ = split_components(tiny, _zeros(tiny), 1.0, 64, min_particles=1)
    assert parents == [0]
    _, parents, _ = split_components(tiny, _zeros(tiny), 1.0, 64, min_particles=8)
    assert parents == []


def test_split_components_creates_no_id_at_or_above_max_fragments():
    """Three pieces of fragment 0 with max_fragments = 2: one new id (1), the third piece stays 0."""
    x = torch.cat([_cells((0, 0, 0), (3, 3, 3)), _cells((5, 0, 0), (8, 3, 2)), _cells((10, 0, 0), (12, 3, 2))])
    out, parents, children = split_components(x, _zeros(x), 1.0, 2)
    assert children == [1] and int(out.max()) == 1
    assert bool((out[27:45] == 1).all())  # the second largest (18) got the new id


def test_plane_cut_positive_side_gets_the_new_id_and_the_band_is_within_the_width():
    """Cutting by the plane x = 2 (normal +x): particles with (x − p)·n ≥ 0 take the new id, the others
    keep theirs; the band is the particles closer than band_width to the plane, tagged with the event."""
    x = torch.tensor([[0.5, 0, 0], [1.7, 0, 0], [2.0, 0, 0], [2.2, 0, 0], [3.5, 0, 0]])
    frag, band, parents, children = plane_cut(x, _zeros(x), _zeros(x), (2, 0, 0), (3, 0, 0), 0.35, 8, tag=2)
    assert frag.tolist() == [0, 0, 1, 1, 1]
    assert band.tolist() == [0, 2, 2, 2, 0]
    assert parents == [0] and children == [1]


def test_plane_cut_leaves_earlier_bands_and_uncut_fragments_alone():
    """A second cut keeps the tag of particles already in a band, cuts only its target fragments, and a
    fragment entirely on one side is not cut (no id, no band)."""
    x = torch.tensor([[0.0, 0, 0], [0.9, 0, 0], [1.1, 0, 0], [2.0, 0, 0], [5.0, 0, 0]])
    frag0 = torch.tensor([0, 0, 0, 0, 1], dtype=torch.int32)
    band0 = torch.tensor([0, 1, 0, 0, 0], dtype=torch.int32)
    frag, band, parents, children = plane_cut(x, frag0, band0, (1, 0, 0), (1, 0, 0), 0.2, 8, tag=2)
    assert band.tolist() == [0, 1, 2, 0, 0]
    assert frag.tolist() == [0, 0, 2, 2, 1] and parents == [0] and children == [2]
    frag, _, parents, _ = plane_cut(x, frag0, band0, (1, 0, 0), (1, 0, 0), 0.2, 8, targets=[1])
    assert parents == [] and torch.equal(frag, frag0)


def test_plane_cut_at_max_fragments_grows_the_band_but_makes_no_id():
    """With every id in use (max_fragments reached) the cut still marks its band but creates no fragment."""
    x = torch.tensor([[0.0, 0, 0], [0.95, 0, 0], [1.05, 0, 0], [2.0, 0, 0]])
    frag0 = torch.tensor([0, 0, 0, 1], dtype=torch.int32)
    frag, band, parents, _ = plane_cut(x, frag0, _zeros(x), (1, 0, 0), (1, 0, 0), 0.1, 2, targets=[0])
    assert parents == [] and torch.equal(frag, frag0) and band.tolist() == [0, 1, 1, 0]


def test_voronoi_band_is_the_distance_to_the_bisector_of_the_two_nearest_sites():
    """Sites at x = 0 and x = 2 (bisector x = 1): a particle at x = 0.7 is 0.3 from the bisector, so in the
    band for a width of 0.31 and not for 0.29 (one at x = 1.2, 0.2 away, for 0.29 but not 0.19); each
    belongs to the nearer site's cell. One site: one cell, no band."""
    x = torch.tensor([[0.7, 0.3, 0.0], [1.2, -0.2, 0.0]])
    seeds = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 9.0, 0.0]])
    cell, band = voronoi_labels(x, seeds, 0.31)
    assert cell.tolist() == [0, 1] and band.tolist() == [1, 1]
    _, band = voronoi_labels(x, seeds, 0.29)
    assert band.tolist() == [0, 1]
    _, band = voronoi_labels(x, seeds, 0.19)
    assert band.tolist() == [0, 0]
    cell, band = voronoi_labels(x, seeds[:1], 10.0)
    assert cell.tolist() == [0, 0] and band.tolist() == [0, 0]


def test_plane_cut_needs_particles_strictly_behind_the_plane():
    """A fragment whose particles all lie on or in front of the plane (one exactly on it) is not cut: the
    far side is d < 0 strictly, and band membership is strictly closer than band_width (exact binary
    distances 0.25)."""
    x = torch.tensor([[1.0, 0, 0], [1.5, 0, 0], [2.0, 0, 0]])
    frag, band, parents, _ = plane_cut(x, _zeros(x), _zeros(x), (1, 0, 0), (1, 0, 0), 0.25, 8)
    assert parents == [] and bool((frag == 0).all()) and bool((band == 0).all())
    x = torch.tensor([[0.5, 0, 0], [0.75, 0, 0], [1.0, 0, 0], [1.25, 0, 0], [1.5, 0, 0]])
    frag, band, _, _ = plane_cut(x, _zeros(x), _zeros(x), (1, 0, 0), (1, 0, 0), 0.25, 8)
    assert frag.tolist() == [0, 0, 1, 1, 1] and band.tolist() == [0, 0, 1, 0, 0]


def test_voronoi_band_is_strictly_closer_than_the_width():
    """A particle exactly band_width from the bisector (sites at 0 and 2, particle at 0.75: 0.25 away, exact
    in binary) is outside the band."""
    seeds = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    x = torch.tensor([[0.75, 0.0, 0.0], [0.8, 0.0, 0.0]])
    _, band = voronoi_labels(x, seeds, 0.25)
    assert band.tolist() == [0, 1]


def test_split_components_splits_a_fragment_of_exactly_two_minimal_pieces():
    """A fragment of 2·min_particles particles in two pieces of min_particles each is split (the smallest
    splittable fragment)."""
    x = torch.cat([_cells((0, 0, 0), (2, 2, 2)), _cells((10, 0, 0), (12, 2, 2))])  # 8 + 8
    out, parents, children = split_components(x, _zeros(x), 1.0, 64, min_particles=8)
    assert parents == [0] and children == [1] and sorted(out.tolist()) == [0] * 8 + [1] * 8
