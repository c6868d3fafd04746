"""`sim.grid_storage = "boxes"` (docs/DESIGN.md "Grid storage: per-fragment boxes"): after a latch the
simulator keeps each fragment's field in its own dense box, refitted every frame. The physics is the slot
storage's: a plane cut into two pieces advances bitwise as with slots on the CPU (every node's deposits are
added in particle order in both), Voronoi pieces as close as a different Gauss–Seidel order at nodes of three
or more fields allows; mass is never dropped, a stencil that leaves its box redoes the frame with larger
boxes, and nodes with more fields than `field_slots` are counted."""

from dataclasses import replace

import pytest
import torch
from test_transfer_launch import slab

from fracture_gs.sim.physics.contact import N_PAIR_STATS, NORMAL_LATCHED, PAIR_GATED, STAT_FIRST_T, STAT_GATED
from fracture_gs.sim.topology import FractureEvent

FRAME = 4e-3


def advanced(seed, device, storage, fragments, frames=3, slots=8, push=0.5, variant="full"):
    """The slab latched, every piece pushed toward its middle, advanced `frames` frames."""
    sim, topo = slab(seed, device, fragments, slots, storage=storage, variant=variant)
    sim.cfg.contact.friction = 0.3
    sim.latch(topo)
    sim.particles.v.copy_(push * (0.5 - sim.particles.x))
    for _ in range(frames):
        sim.advance(FRAME)
    return sim


def deposited_mass(sim) -> float:
    """Σ of the boxes' nodal masses after a fresh fit and P2G of the current state (G2P leaves them empty)."""
    with sim._stream_scope():
        sim.fit_active_box(FRAME)
        sim.set_clock(1e-3)
        sim.p2g(1e-3)
    return float(sim.boxes.mp[: sim.boxes.nodes, 3].double().sum())


def test_a_plane_cut_in_boxes_is_the_slot_storages_bitwise_on_the_cpu(device, seed):
    """Two pieces pressed together for 3 frames: the same trajectories (bitwise on the CPU; on a GPU, where
    atomics sum in any order, to float32 rounding), the same contact counts and first contact, the statistics'
    sums over nodes to float32 rounding (the boxes visit the nodes in another order), and no redone frame."""
    slots, boxes = (advanced(seed, device, s, 2) for s in ("slots", "boxes"))
    assert boxes.boxed and not slots.boxed and boxes.frame_redos == 0
    assert float(slots.grid.contact_stats[STAT_GATED]) > 10, "the pieces pressed into each other"
    for name in ("x", "v", "C", "F"):
        a, b = getattr(slots.particles, name), getattr(boxes.particles, name)
        if device == "cpu":
            assert torch.equal(a, b), name
        else:
            torch.testing.assert_close(b, a, rtol=1e-4, atol=1e-5)
    a, b = slots.grid.contact_stats.cpu(), boxes.grid.contact_stats.cpu()
    assert torch.equal(a[[0, 1, STAT_FIRST_T]], b[[0, 1, STAT_FIRST_T]]), (a, b)
    torch.testing.assert_close(b[2:], a[2:], rtol=1e-4, atol=1e-6 * float(a[5]))
    pairs = lambda sim: sim.grid.pair_stats.cpu().view(-1, N_PAIR_STATS)  # noqa: E731
    assert torch.equal(pairs(slots)[:, PAIR_GATED], pairs(boxes)[:, PAIR_GATED]), "gated nodes per fragment pair"


def test_voronoi_pieces_in_boxes_follow_the_slot_storage(device, seed):
    """Six pieces, mass-gradient normals and friction: the boxes' trajectories stay within 1 % of the slots'
    (they differ only in the order of the pairwise projections at nodes of three or more fields), the
    contact fires as often, and momentum changes only by gravity and the walls (none reached here)."""
    slots, boxes = (advanced(seed, device, s, 6) for s in ("slots", "boxes"))
    P, Q = slots.particles, boxes.particles
    scale = float(P.v.norm(dim=1).max())
    assert float((P.x - Q.x).abs().max()) <= 1e-2 * FRAME * 3 * scale + 1e-6
    assert float((P.v - Q.v).norm(dim=1).max()) <= 1e-2 * scale
    a, b = float(slots.grid.contact_stats[STAT_GATED]), float(boxes.grid.contact_stats[STAT_GATED])
    assert a > 10 and abs(a - b) <= 0.05 * a, (a, b)
    m = Q.mass.double()[:, None]
    p = (m * Q.v.double()).sum(0)
    p0 = (m * (0.5 * (0.5 - Q.x.double()))).sum(0)  # not the start state: only a sanity bound on the drift
    assert bool(torch.isfinite(p).all()) and float((p - p0).norm()) < float(m.sum()) * 1.0


def test_a_stencil_that_leaves_its_box_redoes_the_frame_with_larger_boxes(device, seed):
    """Boxes are fitted with the travel the frame's start speeds allow; a piece that is then kicked faster (a
    particle region's impulse in the frame) leaves its box: P2G counts it, the frame is redone with more
    slack, and the end state has every particle's mass in its own box."""
    sim, topo = slab(seed, device, 2, storage="boxes")
    sim.latch(topo)
    P = sim.particles
    sim.advance(FRAME)
    assert sim.frame_redos == 0
    # a velocity the box fit does not know, set between the fit and the substeps
    fit = sim.fit_active_box

    def fit_then_kick(horizon):
        vmax = fit(horizon)
        P.v[P.fragment == 1] += torch.tensor([0.0, 25.0, 0.0], device=P.v.device)  # 6 cells in the frame
        return vmax

    sim.fit_active_box = fit_then_kick
    sim.advance(2 * FRAME)
    assert sim.frame_redos >= 1 and sim.runner.box_slack > 0, "the escape was caught and the frame redone"
    sim.fit_active_box = fit
    total = float(P.mass.double().sum())
    assert abs(deposited_mass(sim) - total) <= 1e-5 * total


def test_more_fields_than_slots_are_counted_and_keep_their_mass(device, seed):
    """Two coupled fields per node for six pieces: nodes where a third piece has mass leave it uncoupled and
    count it; the boxes still hold every particle's mass, and the metrics row reports the overflow."""
    sim = advanced(seed, device, "boxes", 6, frames=1, slots=2)
    assert sim.slot_overflow > 0 and sim.slot_overflow_total > 0, "the overflow must be counted"
    tracker = sim.diagnostics_tracker()
    sim.advance(FRAME)
    assert tracker.history[-1]["slot_overflow"] > 0
    assert tracker.history[-1]["pool_rows"] == 0, "boxes keep no pool of multi-field nodes"
    P = sim.particles
    total = float(P.mass.double().sum())
    assert abs(deposited_mass(sim) - total) <= 1e-5 * total
    assert bool(torch.isfinite(P.v).all())


@pytest.mark.parametrize("fragments", [2, 6])
def test_boxes_move_without_changing_what_recorded_launches_bake_in(device, seed, fragments):
    """Every frame refits the boxes to the moving pieces, yet the launches' buffers and sizes (the layout key a
    recorded CUDA graph bakes in) stay the same, so one recorded substep keeps replaying; on CUDA the replayed
    frames equal plain launches."""
    runs = []
    for graphs in (False, True):
        sim, topo = slab(seed, device, fragments, storage="boxes")
        sim.options = replace(sim.options, use_graphs=graphs)
        sim.latch(topo)
        P = sim.particles
        P.v.copy_(0.5 * (0.5 - P.x) + torch.tensor([0.0, 3.0, 0.0], device=P.x.device))  # and a drift along y
        sim.advance(FRAME)
        key, lo = sim.boxes.layout_key, sim.boxes.lo.clone()
        for _ in range(3):
            sim.advance(FRAME)
            assert sim.boxes.layout_key == key
        assert not torch.equal(sim.boxes.lo, lo), "the boxes followed the pieces"
        runs.append(sim)
    a, b = (r.particles for r in runs)
    if device == "cpu":  # no graphs on the CPU: both ran the same launches
        assert torch.equal(a.x, b.x)
        return
    assert runs[1].runner.graph is not None
    torch.testing.assert_close(b.x, a.x, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(b.v, a.v, rtol=1e-3, atol=1e-4)


def test_local_multifield_in_boxes_detects_what_the_slots_detect_and_projects_nothing(device, seed):
    """Local Multi-Field (per-fragment fields, no contact projection) on six pressed pieces: the boxes count
    the same approaching node pairs as the slots and move every particle as the slots do (no projection, so
    the order of the pairs cannot matter: bitwise on the CPU), unlike FractureFields, which projects."""
    slots, boxes = (advanced(seed, device, s, 6, variant="local_multifield") for s in ("slots", "boxes"))
    full = advanced(seed, device, "boxes", 6)
    assert boxes.boxed
    a, b = float(slots.grid.contact_stats[STAT_GATED]), float(boxes.grid.contact_stats[STAT_GATED])
    assert a > 10 and (a == b if device == "cpu" else abs(a - b) <= 0.01 * a), (a, b)  # GPU: atomics' order
    if device == "cpu":
        assert torch.equal(slots.particles.x, boxes.particles.x)
    else:
        torch.testing.assert_close(boxes.particles.x, slots.particles.x, rtol=1e-4, atol=1e-5)
    assert float((full.particles.v - boxes.particles.v).abs().max()) > 1e-3, "FractureFields projects"


def test_auto_storage_keeps_boxes_when_a_second_latch_makes_a_third_piece(device, seed):
    """`grid_storage = "auto"`: a plane cut into two pieces runs in per-fragment boxes (latched normal); a later
    latch that splits one piece again (three pieces: mass-gradient normals) keeps them, with a box for the new
    piece. The latch is impulse-free (x, v, C, F unchanged to the bit), and the boxes then hold every particle's
    mass."""
    sim, topo = slab(seed, device, 2, storage="auto")
    sim.latch(topo)
    P = sim.particles
    P.v.copy_(0.5 * (0.5 - P.x))
    sim.advance(FRAME)
    assert sim.boxed and sim.boxes.K == 2 and sim.normal_mode == NORMAL_LATCHED
    fragment = topo.fragment.clone()
    fragment[(topo.fragment == 1) & (P.x[:, 1].cpu() > 0.5)] = 2  # the second piece cut along y
    cut = FractureEvent("plane", sim.time, sim.frame, (1,), (2,), (0.5, 0.5, 0.5), (0.0, 1.0, 0.0))
    again = replace(topo, fragment=fragment, events=list(topo.events) + [cut], latch_frame=sim.frame)
    before = {k: getattr(P, k).clone() for k in ("x", "v", "C", "F")}
    sim.latch(again)
    assert sim.boxed and sim.n_fragments == 3
    for k, t in before.items():
        assert torch.equal(getattr(P, k), t), f"the latch changed {k}"
    sim.advance(FRAME)
    total = float(P.mass.double().sum())
    assert abs(deposited_mass(sim) - total) <= 1e-5 * total
    assert bool(torch.isfinite(P.x).all()) and sim.frame_redos == 0
