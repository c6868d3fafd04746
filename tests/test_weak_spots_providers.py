"""Weak spots of the fracture providers (issue 34): which band tag a particle keeps across cuts, which piece keeps
its parent's id, how wide a Voronoi band is, and the id bounds. Labels only, on the CPU, in milliseconds. Every test
names the bug it was checked against (applied by hand to the package, the test failed, then reverted)."""

from types import SimpleNamespace

import numpy as np
import torch

from fracture_gs.config import OraclePlane, TopologyConfig
from fracture_gs.sim.providers import OracleProvider, VoronoiProvider
from fracture_gs.sim.providers.cuts import plane_cut, split_components, voronoi_labels


def lattice(lo, counts, step):
    """Points on a regular lattice from `lo`, `counts` per axis, spacing `step`: [prod(counts), 3] float32."""
    axes = [lo[a] + step * torch.arange(counts[a], dtype=torch.float64) for a in range(3)]
    return torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).float()


def fake_sim(x, dx=0.1, max_fragments=64, frame=1):
    """What a provider reads of a simulator: the particles' positions, Δx, max_fragments, time and frame."""
    return SimpleNamespace(
        particles=SimpleNamespace(x=x), grid=SimpleNamespace(dx=dx), cfg=SimpleNamespace(max_fragments=max_fragments),
        time=0.01 * frame, frame=frame,
    )  # fmt: skip


def test_a_later_cut_keeps_the_band_tags_of_earlier_cuts():
    """A particle's band tag is the 1-based index of the first event whose band it joined (`release = "first"`
    releases exactly event 1's band, so a later cut must not re-tag it): a second plane through the first band tags
    only the untagged particles within its band width, and particles in neither band stay 0.
    Bug tried: `plane_cut` without `& (band == 0)` (a later cut re-tags an earlier band): fails here."""
    x = lattice((0.0, 0.0, 0.0), (21, 21, 3), 0.05)  # [0, 1] × [0, 1] × [0, 0.1]
    fragment = (x[:, 0] >= 0.5).to(torch.int32)
    band = ((x[:, 0] - 0.5).abs() < 0.075).to(torch.int32)  # event 1: the plane x = 0.5
    frag2, band2, parents, children = plane_cut(x, fragment, band, (0.0, 0.5, 0.0), (0.0, 1.0, 0.0), 0.075, 64, tag=2)
    near1 = (x[:, 0] - 0.5).abs() < 0.075
    near2 = (x[:, 1] - 0.5).abs() < 0.075
    assert bool((near1 & near2).any()), "the bands cross"
    assert torch.equal(band2[near1], torch.ones_like(band2[near1])), "event 1's band keeps tag 1"
    assert torch.equal(band2[near2 & ~near1], torch.full_like(band2[near2 & ~near1], 2)), "the new band is tagged 2"
    assert int(band2[~near1 & ~near2].abs().sum()) == 0, "no particle outside both bands is in the band"
    assert parents == [0, 1] and children == [2, 3], "each fragment the plane crosses gives one new id"


def test_a_plane_cut_gives_the_positive_side_new_ids_below_max_fragments():
    """Each fragment the plane crosses keeps its id on the negative side (d < 0) and gives the positive side
    (d ≥ 0, a particle exactly on the plane included, as `Topology.from_plane` labels it) the next free id, in
    fragment order; no id reaches `max_fragments` (a fragment that would need one stays whole, its band still
    tagged); a fragment the plane misses is untouched.
    Bugs tried: `next_id >= max_fragments` as `>` (an id equal to max_fragments); `d >= 0` as `d > 0`; the band
    tagged only for fragments that got an id. Each fails here."""
    x = lattice((0.0, 0.0, 0.0), (11, 3, 3), 0.1)  # x = 0, 0.1, …, 1.0: one column exactly on x = 0.5
    fragment = torch.zeros(len(x), dtype=torch.int32)
    fragment[x[:, 1] > 0.15] = 1
    fragment[x[:, 0] < 0.25] = 2  # missed by the plane x = 0.5
    on = x[:, 0] == 0.5
    assert bool(on.any())
    frag, band, parents, children = plane_cut(x, fragment, torch.zeros_like(fragment), (0.5, 0, 0), (1, 0, 0), 0.05, 4)
    assert parents == [0] and children == [3], "fragment 0 takes id 3; fragment 1 would need id 4 = max_fragments"
    assert int(frag.max()) < 4
    pos0 = (fragment == 0) & (x[:, 0] >= 0.5)
    assert torch.equal(frag[pos0], torch.full_like(frag[pos0], 3)) and bool((frag[on & (fragment == 0)] == 3).all())
    assert torch.equal(frag[fragment != 0], fragment[fragment != 0]), "fragments 1 (no id left) and 2 (missed) keep"
    assert torch.equal(band.bool(), on & (fragment != 2)), "the band: |d| < width in every fragment the plane crosses"


def pieces(sizes_and_corners, step=0.05):
    """Separate lattice blocks of one fragment (id 3; a block of fragment 0 elsewhere sets the largest id to 3):
    (x [N, 3], fragment [N], the block index of each particle, −1 for fragment 0's block)."""
    xs, block = [], []
    for b, (counts, corner) in enumerate(sizes_and_corners):
        xs.append(lattice(corner, counts, step))
        block.append(torch.full((len(xs[-1]),), b))
    xs.append(lattice((3.0, 3.0, 3.0), (3, 3, 3), step))
    block.append(torch.full((27,), -1))
    x, block = torch.cat(xs), torch.cat(block)
    return x, torch.where(block >= 0, 3, 0).to(torch.int32), block


def test_after_a_component_split_the_largest_piece_keeps_the_parents_id():
    """`split_components`: every disconnected piece of a fragment with at least `min_particles` particles gets its
    own id, except the largest, which keeps the parent's id (its identity, pairs and contact history continue);
    the new ids follow the pieces by decreasing size; pieces below `min_particles` stay with the parent; no id
    reaches `max_fragments`. Pieces listed here smallest first, so list order decides nothing.
    Bugs tried: `np.argsort(-sizes)` as `np.argsort(sizes)` (the smallest piece keeps the parent's id), `order[1:]`
    as `order[:-1]`, `sizes[c] >= min_particles` as `>`, the max_fragments bound `>=` as `>`. Each fails here."""
    blocks = [
        ((2, 2, 1), (0.0, 0.0, 0.0)),  # 4 particles: below min_particles, stays with the parent
        ((2, 2, 2), (1.0, 0.0, 0.0)),  # 8: exactly min_particles, a piece
        ((3, 3, 3), (0.0, 1.0, 0.0)),  # 27
        ((4, 4, 4), (1.0, 1.0, 1.0)),  # 64: the largest
    ]
    x, fragment, block = pieces(blocks)
    out, parents, children = split_components(x, fragment, h=0.1, max_fragments=64, min_particles=8)
    want = {0: 3, 1: 5, 2: 4, 3: 3, -1: 0}
    for b, k in want.items():
        assert torch.equal(out[block == b], torch.full_like(out[block == b], k)), f"block {b} should be fragment {k}"
    assert parents == [3, 3] and children == [4, 5]
    capped, parents, children = split_components(x, fragment, h=0.1, max_fragments=5, min_particles=8)
    assert children == [4] and int(capped.max()) == 4, "id 5 = max_fragments is never made"
    assert torch.equal(capped[block == 1], torch.full_like(capped[block == 1], 3)), "the piece without an id stays"


def test_the_voronoi_band_is_band_width_from_the_bisector_on_either_side():
    """The Voronoi band: particles whose distance to the bisector with their second-nearest site is below the band
    width, on both sides. Two sites on the x axis 0.4 apart put the bisector at x = 0.5: particles 0.049 away are in
    the band, 0.051 away are not (band width 0.05 = 0.5 Δx through the provider, which scales `band_width` by Δx).
    Bugs tried: the gap without its ½ (the band half as wide), `band_width · Δx / 2` in the provider, `gap <` as
    `gap <=`; each fails here."""
    offsets = torch.tensor([0.0, 0.02, -0.02, 0.049, -0.049, 0.051, -0.051, 0.1, -0.1], dtype=torch.float64)
    x = torch.zeros(len(offsets), 3, dtype=torch.float64)
    x[:, 0] = 0.5 + offsets
    x[:, 1] = torch.linspace(-0.2, 0.2, len(offsets), dtype=torch.float64)  # along the bisector: no effect
    seeds = torch.tensor([[0.3, 0.0, 0.0], [0.7, 0.0, 0.0]], dtype=torch.float64)
    cell, band = voronoi_labels(x, seeds, 0.05)
    want = offsets.abs() < 0.05
    assert torch.equal(band.bool(), want), band
    assert torch.equal(cell.long(), (offsets >= 0).long()), "each particle in its nearest site's cell"
    exact = torch.tensor([[0.75, 0.0, 0.0], [0.25, 0.0, 0.0], [0.625, 0.0, 0.0]], dtype=torch.float64)
    _, edge = voronoi_labels(exact, torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], dtype=torch.float64), 0.25)
    assert edge.tolist() == [0, 0, 1], "exactly band_width away (0.25, binary-exact) is outside: |d| < width"
    cfg = TopologyConfig(provider="voronoi", cells=2, band_width=0.5, split_components=False, latch_frame=0)
    sites = torch.cat([seeds.float(), x.float()])  # the sites are drawn from the particles: make them the two seeds
    provider = VoronoiProvider(cfg)
    import fracture_gs.sim.providers.voronoi as V

    before = V.voronoi_sites
    V.voronoi_sites = lambda x, cells, *a, **k: seeds.to(x.device)
    try:
        topo = provider(fake_sim(sites, dx=0.1))
    finally:
        V.voronoi_sites = before
    assert torch.equal(topo.band[2:].bool(), want), "the provider's band is band_width · Δx wide"


def test_repeated_oracle_planes_tag_each_band_with_its_event():
    """Timed oracle planes: the first latch tags its band 1, the second plane (one frame later) tags only the
    particles of its own band that the first did not, with 2, and cuts every fragment it crosses.
    Bugs tried: the later cut's tag as 1 (`tag=len(t.events)`), and re-tagging (`& (band == 0)` dropped)."""
    x = lattice((0.0, 0.0, 0.0), (21, 21, 2), 0.05)
    planes = [OraclePlane((0.5, 0.0, 0.0), (1.0, 0.0, 0.0), 1, None), OraclePlane((0.0, 0.5, 0.0), (0.0, 1.0, 0.0), 2)]
    cfg = TopologyConfig(provider="oracle", band_width=0.75, split_components=False, planes=planes)
    provider = OracleProvider(cfg)
    t1 = provider(fake_sim(x, frame=1))
    t2 = provider(fake_sim(x, frame=2))
    near1 = (x[:, 0] - 0.5).abs() < 0.075
    near2 = (x[:, 1] - 0.5).abs() < 0.075
    assert torch.equal(t1.band.bool(), near1)
    assert torch.equal(t2.band[near1], torch.ones_like(t2.band[near1]))
    assert torch.equal(t2.band[near2 & ~near1], torch.full_like(t2.band[near2 & ~near1], 2))
    quadrant = (x[:, 0] >= 0.5).int() + 2 * (x[:, 1] >= 0.5).int()
    ids = {int(q): set(t2.fragment[quadrant == q].tolist()) for q in range(4)}
    assert all(len(s) == 1 for s in ids.values()) and len({next(iter(s)) for s in ids.values()}) == 4, ids
    assert np.array_equal(sorted(t2.fragment.unique().tolist()), [0, 1, 2, 3])
