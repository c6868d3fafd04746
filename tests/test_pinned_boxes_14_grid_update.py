"""The boxes' grid update (`boxes.kernels.box_grid_update`) node by node, from (p, m) values set by hand.

With the contact gate closed (fill mass ∞), every field at every node of every box takes the rule: v = p/m + Δt g
where m > ε_m, then the boundaries at the node's position x_i = origin + node·Δx; v = 0 where 0 < m ≤ ε_m; no
write where m = 0 (no particle reached it, no G2P reads it). This holds alike where one field has mass, where two
fields meet (the leader's register path), where three or more do (the sweep), and for fields past the `slots` a
leader couples (each counted once as a slot overflow). The boundary is an oblique sticky plane on a grid whose
origin is off zero, so a position built from the wrong node component, without the origin or without Δx, puts
nodes on the wrong side. The boxes are fitted tight, all overlap, and box 0's buffer index 1 holds mass: a partner
list's padding past its end (four partners are loaded at a time) that pointed at a real buffer index would read
that mass as a field. The second test runs the same rule with six overlapping boxes (five partners each: the
padded loads run twice per node) through the kernel's own source compiled with Warp's index checks (debug mode),
which stops on any index past a vector's end.
"""

import pytest
import torch
import warp as wp

import fracture_gs.sim.boxes.fragment_boxes as fb
from fracture_gs.config import PlaneBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.boxes.kernels import GRID_UPDATES, GRID_UPDATES_LATCHED, MAX_FIELDS, grid_update_kernel
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from fracture_gs.sim.storage import COUNT_SLOT_OVERFLOW, N_COUNTS

n, DX, DT, EPS_M = 16, 1.0 / 16, 2e-3, 1e-6
ORIGIN = (0.3, -0.4, 0.15)
GRAVITY = (0.7, -1.3, -9.8)
SENTINEL = 7.0


def _boxes(K, seed):
    """Boxes fitted tight (slack 0) to a jittered lattice in the middle of a 16³ grid: K = 3, three slabs along x
    (the middle one 1.5 cells thick, so all three boxes overlap); K = 6, fragments assigned at random (every box
    spans the block). Each buffer index of the boxes then gets m = 0 (a fifth), m = ε_m / 2 (a tenth), m = ε_m
    exactly (a tenth: inactive, the threshold is strict) or m ∈ [0.5, 1.5]·10⁻³ kg, and a random momentum; buffer
    index 1 gets mass and index 0 (box 0's lowest node, inside every other box when K = 6) a mass below ε_m;
    velocities start at a sentinel."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    ax = torch.arange(0.3, 0.7, 0.5 * DX, dtype=torch.float64)
    xi = torch.stack(torch.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    xi = xi + (torch.rand(xi.shape, generator=g, dtype=torch.float64) - 0.5) * 0.2 * DX
    x = (torch.tensor(ORIGIN, dtype=torch.float64) + xi).float()
    if K == 3:
        fragment = (xi[:, 0] >= 0.45).int() + (xi[:, 0] >= 0.45 + 1.5 * DX).int()
    else:
        fragment = torch.randint(0, K, (len(x),), generator=g, dtype=torch.int32)
    boxes = FragmentBoxes((n, n, n), ORIGIN, DX, "cpu", max_fragments=8)
    boxes.fit(x, fragment.to(torch.int32), slack=0)
    assert boxes.K == K
    starts = boxes.over_start[: K + 1].long()
    assert (starts[1:] - starts[:-1]).tolist() == [K - 1] * K, "every box overlaps every other"
    N = boxes.nodes
    u = torch.rand(N, generator=g)
    live = 1e-3 * (0.5 + torch.rand(N, generator=g))
    m = torch.where(u < 0.2, 0.0, torch.where(u < 0.3, 0.5 * EPS_M, torch.where(u < 0.4, EPS_M, live)))
    m[1] = 1e-3
    m[0] = 0.5 * EPS_M
    boxes.mp[:N, 3] = m
    boxes.mp[:N, :3] = 1e-3 * torch.randn(N, 3, generator=g)
    boxes.vel.fill_(SENTINEL)
    return boxes


def _plane():
    """A sticky plane through the block's middle with normal (1, 2, −3)/√14, moved until no node lies within
    10⁻³ Δx of it (float32 may round such a node to either side)."""
    normal = torch.tensor([1.0, 2.0, -3.0], dtype=torch.float64) / 14**0.5
    point = torch.tensor(ORIGIN, dtype=torch.float64) + torch.tensor([0.51, 0.47, 0.53], dtype=torch.float64)
    nodes = torch.stack(torch.meshgrid(*[torch.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    xi = torch.tensor(ORIGIN, dtype=torch.float64) + nodes.double() * DX
    while bool((((xi - point) @ normal).abs() < 1e-3 * DX).any()):
        point = point + 1e-2 * DX * normal
    return point, normal


def _expected(boxes, K, slots, point, normal):
    """The rule per buffer index (see the module docstring) and the slot overflows: at a node where F fields hold
    m > ε_m, F − slots beyond the leader's slots."""
    N = boxes.nodes
    mp = boxes.mp[:N].double()
    m = mp[:, 3]
    eps = float(torch.tensor(EPS_M, dtype=torch.float32))  # ε_m as the kernel reads it (float32)
    want = torch.full((N, 3), SENTINEL, dtype=torch.float64)
    want[(m > 0) & (m <= eps)] = 0.0
    live = m > eps
    v = mp[:, :3] / m.clamp_min(1e-30)[:, None] + DT * torch.tensor(GRAVITY, dtype=torch.float64)
    nodes = torch.empty(N, 3, dtype=torch.long)
    fields = torch.zeros(n, n, n, dtype=torch.long)
    for k in range(K):
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        d = [int(s) for s in boxes.dims[k]]
        local = torch.stack(torch.meshgrid(*[torch.arange(s) for s in d], indexing="ij"), -1).reshape(-1, 3)
        nodes[a:b] = boxes.lo[k].long() + local
        at = nodes[a:b][live[a:b]]
        fields[at[:, 0], at[:, 1], at[:, 2]] += 1
    xi = torch.tensor(ORIGIN, dtype=torch.float64) + nodes.double() * DX
    behind = (xi - point) @ normal < 0
    v[behind] = 0.0
    want[live] = v[live]
    overflow = int((fields - slots).clamp_min(0).sum())
    return want, fields, behind, live, overflow


def _update(boxes, K, slots):
    point, normal = _plane()
    walls = Boundaries([PlaneBoundary(point=tuple(point.tolist()), normal=tuple(normal.tolist()), mode="sticky")],
                       "cpu", (n, n, n), 0)  # fmt: skip
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    centroids = wp.zeros(K, dtype=wp.vec3, device="cpu")
    boxes.update(clock.view, EPS_M, GRAVITY, float("inf"), centroids, wp.from_torch(counts), walls.colliders,
                 mass_gradient=True, slots=slots)  # fmt: skip
    want, fields, behind, live, overflow = _expected(boxes, K, slots, point, normal)
    return want, fields, behind, live, overflow, counts


@pytest.mark.parametrize("slots", [2, 3])
def test_every_field_at_every_node_takes_p_over_m_gravity_and_the_plane(slots):
    """Three tight overlapping boxes, the gate closed: each buffer index's velocity is the rule (float32 rounding),
    the sentinel stays where m = 0, nodes of one, two and three fields and nodes on both sides of the plane all
    occur, and the slot overflows are exactly Σ max(0, F − slots) over the nodes (3 fields with 2 slots: one each;
    with 3 slots: none)."""
    boxes = _boxes(3, 140)
    assert float(boxes.mp[1, 3]) > EPS_M, "box 0's buffer index 1 holds mass"
    want, fields, behind, live, overflow, counts = _update(boxes, 3, slots)
    for F in (1, 2, 3):
        assert int((fields == F).sum()) > 5, f"nodes of {F} fields"
    assert int((live & behind).sum()) > 20 and int((live & ~behind).sum()) > 20, "both sides of the plane"
    got = boxes.vel[: boxes.nodes].double()
    err = (got - want).abs().max(1).values / want.abs().max(1).values.clamp_min(1.0)
    assert float(err.max()) < 1e-5, f"worst buffer index {int(err.argmax())}"
    assert int(counts[COUNT_SLOT_OVERFLOW]) == overflow
    assert (overflow > 0) == (slots == 2)


def test_six_overlapping_boxes_under_index_checks(monkeypatch):
    """Six tight boxes of randomly mixed fragments (five partners each, so a leader loads its partners' masses in
    two batches of four, the second padded) through the grid update compiled from its own source with Warp's index
    checks: no index leaves its vector (the build stops otherwise), every velocity is the rule, nodes of up to six
    fields occur, and with 4 slots the overflows are Σ max(0, F − 4)."""
    ensure_warp()
    checked = wp.kernel(
        GRID_UPDATES[False, False].func, name="box_grid_update_checked", module="unique",
        module_options={"mode": "debug", "enable_backward": False},
    )  # fmt: skip
    monkeypatch.setattr(fb, "grid_update_kernel", lambda record, fast, mode: checked)
    boxes = _boxes(6, 141)
    slots = 4
    assert slots < MAX_FIELDS
    lo0 = boxes.lo[0].long()
    inside = (boxes.lo[1:6].long() <= lo0).all(1) & (lo0 < boxes.lo[1:6].long() + boxes.dims[1:6].long()).all(1)
    assert bool(inside.all()), "box 0's buffer index 0 is a node of every other box"
    want, fields, _, _, overflow, counts = _update(boxes, 6, slots)
    assert int(fields[tuple(lo0.tolist())]) >= 2, "other fields are active where box 0's inactive index 0 lies"
    assert int((fields >= 5).sum()) > 5, "nodes of five or six fields"
    got = boxes.vel[: boxes.nodes].double()
    err = (got - want).abs().max(1).values / want.abs().max(1).values.clamp_min(1.0)
    assert float(err.max()) < 1e-5
    assert int(counts[COUNT_SLOT_OVERFLOW]) == overflow > 0


def test_a_launch_takes_the_exact_build_unless_fast_math_is_asked_for():
    """`grid_update_kernel` picks the build a launch runs: without fast math (the CPU) the exact build of the
    module, whatever the normals' mode, so CPU results stay bitwise the slot storage's; with fast math the
    latched-normal build for the plane cut (mode compiled in) and the mode-reading fast build for mass-gradient
    normals; the statistics compiled in exactly when asked for (`record`)."""
    for record in (True, False):
        for mode in (NORMAL_LATCHED, NORMAL_MASS_GRADIENT):
            exact = grid_update_kernel(record, False, mode)
            assert exact is GRID_UPDATES[record, False]
            assert not exact.module.options.get("fast_math", False)
        assert grid_update_kernel(record, True, NORMAL_LATCHED) is GRID_UPDATES_LATCHED[record]
        assert grid_update_kernel(record, True, NORMAL_MASS_GRADIENT) is GRID_UPDATES[record, True]
        for fast in (GRID_UPDATES_LATCHED[record], GRID_UPDATES[record, True]):
            assert fast.module.options["fast_math"]
        for kernel in (GRID_UPDATES[record, False], GRID_UPDATES[record, True], GRID_UPDATES_LATCHED[record]):
            assert ("_quiet" in kernel.key) == (not record), "a quiet build is named so in profiles"
