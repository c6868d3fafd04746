"""Hand-written bug campaign, per-fragment boxes (`sim.boxes`): rules the earlier tests left open.

- `sim.field_slots` = S counts the leader's own field: at a node where n fields hold mass, the contact couples the
  first S of them (the leader and S − 1 partners) and each of the other n − S is counted once as a slot overflow.
  Counted by hand from the fields' masses, for S = 2 and 3 on four quadrant fragments whose boxes meet along the
  centre column (nodes of three and four fields).
- The boxes a latch makes are each fragment's stencils plus one node each way: motion under a cell before the
  next frame's fit (direct `Simulator.substep` calls) escapes no box."""

import pytest
import torch
import warp as wp
from simutil import block, config, particles

from fracture_gs import sim as S
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.storage import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW, N_COUNTS
from fracture_gs.sim.topology import Topology

N, n, DT, EPS_M = 2000, 16, 1e-3, 1e-9


def _quadrants(seed: int = 0):
    """Particles in the middle of a 16³ grid, four fragments by (x, y) quadrant, deposited into their boxes."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    x = 0.3 + 0.4 * torch.rand(N, 3, generator=g)
    fragment = ((x[:, 0] > 0.5).int() + 2 * (x[:, 1] > 0.5).int()).to(torch.int32)
    P = {
        "x": x,
        "v": torch.randn(N, 3, generator=g),
        "C": torch.zeros(N, 3, 3),
        "F": torch.eye(3).repeat(N, 1, 1),
        "mass": torch.ones(N),
        "volume": torch.full((N,), 1e-4),
        "stress": torch.zeros(N, 3, 3),
        "fragment": fragment,
    }
    P = {k: t.contiguous() for k, t in P.items()}
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "F": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t, dtype=types.get(k)) for k, t in P.items()}
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, "cpu")
    boxes.fit(P["x"], P["fragment"])
    return P, w, boxes


@pytest.mark.parametrize("slots", [2, 3])
def test_slot_overflow_counts_the_fields_beyond_the_slots_at_each_node(slots):
    """S = `slots` fields a node: the leader's own plus S − 1 partners. Each node of n > S fields counts n − S
    overflows, so the total is Σ_nodes max(0, n − S), counted here from the boxes' masses (m > ε_m)."""
    P, w, boxes = _quadrants()
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    cw = wp.from_torch(counts)
    c = FrameClock("cpu", 0)
    c.set(DT, [0.0])
    boxes.p2g(w, c.view, cw)
    centroids = torch.stack([P["x"][P["fragment"] == k].mean(0) for k in range(4)]).contiguous()
    walls = Boundaries([], "cpu", (n, n, n), 0).colliders
    boxes.update(c.view, EPS_M, (0.0, 0.0, 0.0), 0.0, wp.from_torch(centroids, dtype=wp.vec3), cw, walls,
                 slots=slots)  # fmt: skip
    m = boxes.dense(4)[0]  # [4, n, n, n]
    fields = (m > EPS_M).sum(0)  # [n, n, n] fields with mass at each node
    assert int((fields >= 4).sum()) > 0, "the four quadrants meet along the centre column"
    expected = int((fields - slots).clamp_min(0).sum())
    assert expected > 0
    assert int(counts[COUNT_SLOT_OVERFLOW]) == expected


def test_boxes_made_at_a_latch_hold_motion_under_one_cell():
    """After a latch the boxes are every fragment's stencils plus one node (and the slack) each way, so particles
    that move less than a cell after it keep their stencils in their boxes: three substeps at 0.4 Δx each along +x
    (`Simulator.substep`, which refits nothing), the third P2G deposits 0.8 Δx on, where the leading particles'
    stencils have moved one node up (base ⌊32·0.6172 + 0.8 − ½⌋ = 20 after 19), and counts no escape."""
    x, vol = block((0.375, 0.375, 0.375), (0.625, 0.625, 0.625), 1.0 / 64)
    cfg = config(32, variant="full", grid_storage="boxes", dt=1e-3)
    P = particles(x, vol, E=torch.full((len(x),), 1e3))
    sim = S.Simulator(cfg, P, device="cpu")
    sim.latch(Topology.from_plane(x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 1.0 / 64))
    assert sim.boxed
    sim.particles.v[:, 0] = 0.4 * sim.grid.dx / cfg.dt
    for _ in range(3):
        sim.substep()
    assert int(sim.counts[COUNT_ESCAPED]) == 0
