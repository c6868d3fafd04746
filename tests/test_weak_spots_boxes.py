"""Weak spots of the fragment boxes, the slot storage's clears and the simulator's active box (issue 34): each test
proves a bound, a margin or a clear exactly at its edge, where a bug one node or one line off changes the result.
Every test names the bug it was checked against (applied by hand to the package, the test failed, then reverted)."""

import pytest
import torch
import warp as wp
from simutil import block, config, particles
from test_fragment_boxes import DT, EPS_M, GRAVITY, clock, n, no_walls
from test_transfer_launch import slab

from fracture_gs import sim as S
from fracture_gs.config import PlaneBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS

DX = 1.0 / n


def two_pieces(seed, device, count=1200):
    """Random particles in two separate blocks of a 24³ grid (fragment 0 at low x, 1 at high x), random v and C,
    τ = 0, F = I; as the Warp views the box launches take."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    x = 0.3 + 0.15 * torch.rand(count, 3, generator=g)
    fragment = (torch.arange(count) >= count // 2).to(torch.int32)
    x[fragment == 1, 0] += 0.25
    P = {
        "x": x,
        "v": torch.randn(count, 3, generator=g),
        "C": torch.randn(count, 3, 3, generator=g),
        "F": torch.eye(3).expand(count, 3, 3).clone(),
        "mass": 0.5 + torch.rand(count, generator=g),
        "volume": torch.full((count,), 1e-5),
        "stress": torch.zeros(count, 3, 3),
        "fragment": fragment,
    }
    P = {k: t.to(device).contiguous() for k, t in P.items()}
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "F": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t, dtype=types.get(k)) for k, t in P.items()}
    return P, w


def test_a_stencil_one_node_past_its_box_is_an_escape_and_g2p_leaves_it_alone(device, seed):
    """Box k holds the nodes [lo, lo + dims) and a stencil holds base … base + 2. With no slack, the particles that
    set a box's bounds still deposit (their stencil touches the box's last node, inside), while a particle moved
    by exactly one node past the lowest or the highest bound on any axis has one node layer outside: P2G counts it
    once and deposits none of it, and G2P leaves its x, v, C, F untouched (it reads no node of another box).
    Bugs tried: `index_in` with `r >= d` as `r > d` (upper bound off by one), with `r < 0` as `r < -1`; P2G checking
    `base + 1` instead of `base + 2` (a stencil margin one node short); `stencil_inside` (G2P) checking `base + 1`;
    `fragment_bounds` reducing `c + 1` instead of `c + 2`. Each fails here."""
    P, w = two_pieces(seed, device)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), DX, device)
    boxes.fit(P["x"], P["fragment"], slack=0)
    x0 = P["x"].cpu()
    frag = P["fragment"].cpu()
    moved = []  # (particle, axis, ±1): each fragment's extreme particle on each side of each axis
    for k in range(2):  # box 0 starts the buffer, box 1 does not: an index below it is another box's, not < 0
        mine = (frag == k).nonzero().flatten()
        for axis in range(3):
            moved.append((int(mine[torch.argmax(x0[mine, axis])]), axis, 1.0))
            moved.append((int(mine[torch.argmin(x0[mine, axis])]), axis, -1.0))
    for i, axis, sign in moved:
        P["x"][i, axis] += sign * DX
    x1 = P["x"].cpu().double()
    lo, top = boxes.lo.cpu().long(), boxes.lo.cpu().long() + boxes.dims.cpu().long() - 1  # [2, 3]
    for i, axis, sign in moved:  # each moved stencil sticks out by exactly one node on its axis
        b, k = torch.floor(x1[i] / DX - 0.5).long(), int(frag[i])
        assert (b[axis] + 2 == top[k, axis] + 1) if sign > 0 else (b[axis] == lo[k, axis] - 1), (i, axis, sign)
    idx = torch.tensor(sorted({i for i, *_ in moved}))  # a particle extreme on two axes moved on both: one escape
    counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=device)
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw)
    assert int(counts[COUNT_ESCAPED]) == len(idx), "each stencil one node outside its box is one escape"
    kept = float(P["mass"].cpu().double().sum()) - float(P["mass"].cpu().double()[idx].sum())
    assert float(boxes.mp[: boxes.nodes, 3].double().sum()) == pytest.approx(kept, rel=1e-6), "escapes deposit none"
    before = {k: P[k].cpu().clone() for k in ("x", "v", "C", "F")}
    boxes.update(c, EPS_M, GRAVITY, float("inf"), wp.zeros(2, dtype=wp.vec3, device=device), cw, no_walls(device))
    boxes.g2p(w, c, wp.vec3(0.0, 0.0, 0.0), wp.vec3(1.0, 1.0, 1.0), cw)
    rest = torch.ones(len(P["x"]), dtype=torch.bool)
    rest[idx] = False
    for k, old in before.items():
        assert torch.equal(P[k].cpu()[idx], old[idx]), f"G2P changed {k} of an escaped particle"
    assert float((P["v"].cpu()[rest] - before["v"][rest]).abs().max()) > 0, "G2P moved the others"


@pytest.mark.parametrize("slots", [2, 8])
def test_every_field_at_every_node_obeys_the_colliders_after_contact(device, seed, slots):
    """The boundaries act on every field after the contact (Algorithm 1), whether a node holds one field, two (the
    register path), three or more (the sweep), or more than `slots` (the uncoupled overflow): behind a slip plane
    z = 0.5 with normal +z no field's node velocity approaches the plane (v_z ≥ 0). Four fragments by quadrant with
    random velocities and contact by mass gradients make nodes of each kind below the plane.
    Bug tried: the two-field node's register path skipping `apply_boundaries` for either field (it failed here);
    the sweep or the overflow path skipping them likewise."""
    from test_fragment_boxes import state

    P, w, counts, boxes = state(seed, device)
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw)
    plane = Boundaries([PlaneBoundary(point=(0.0, 0.0, 0.5), normal=(0.0, 0.0, 1.0), mode="slip")], device, (n,) * 3)
    m, _, _, _ = boxes.dense(4)
    fill = 0.05 * float(m[m > 0].mean())
    centroids = torch.stack([P["x"][P["fragment"] == k].mean(0) for k in range(4)]).contiguous()
    boxes.update(c, EPS_M, GRAVITY, fill, wp.from_torch(centroids, dtype=wp.vec3), cw, plane.colliders, mu=0.2,
                 slots=slots)  # fmt: skip
    m, _, v, _ = (t.cpu() for t in boxes.dense(4))
    active = m > EPS_M  # [4, n, n, n]
    behind = (torch.arange(n) * DX < 0.5)[None, None, None, :].expand_as(active)
    fields = active.sum(0, keepdim=True).expand_as(active)
    for k in (1, 2, 3):
        assert bool((active & behind & (fields == k)).any()), f"nodes of {k} fields behind the plane"
    assert bool((active & behind & (fields == 4)).any()), "nodes of four fields behind the plane"
    vz = v[..., 2][active & behind]
    assert float(vz.min()) >= -1e-6, f"a field approaches the plane behind it: v_z = {float(vz.min()):.3g}"
    assert float(v[..., 2][active & ~behind].min()) < -1e-2, "in front of the plane fields still fall and approach"


def test_claims_reset_between_frames_also_empty_the_pool_rows(device, seed):
    """A frame's P2G after `Grid.reset_claims` gives the same fields as the first: the reset frees the pool rows
    and their slot owners, so it must also empty their accumulators and band masses (the per-substep clear only
    visits claimed rows). Without it a row claimed anew adds onto last frame's mass.
    Bugs tried: `reset_claims` without `_mp[n_nodes:].zero_()` (the pool's mass doubles), without `band.zero_()`
    (the band masses double); both fail here."""
    sim, topo = slab(seed, device, n=1000, storage="slots")
    sim.latch(topo)
    with sim._stream_scope():
        sim.fit_active_box(4e-3)
        sim.p2g(DT)
        m1, b1 = sim.grid.mass.cpu().clone(), sim.grid.band_mass.cpu().clone()
        rows = int(sim.grid.rows_used())
        sim.grid.reset_claims()
        sim.p2g(DT)
        m2, b2 = sim.grid.mass.cpu(), sim.grid.band_mass.cpu()
    assert rows > 50 and float(b1.sum()) > 0, "the cut gives pool rows with band mass"
    torch.testing.assert_close(m2, m1, rtol=1e-6, atol=1e-9)
    torch.testing.assert_close(b2, b1, rtol=1e-6, atol=1e-9)


def test_a_shadow_grid_cleared_before_each_deposit_holds_one_deposit(device, seed):
    """The diagnostics' shadow P2G (`target=` a Grid) clears the whole grid first (`Grid.clear`): two deposits in a
    row give the fields of one (mass, band mass and each fragment's mass Σ_i m_i^k = that fragment's particle mass).
    Bugs tried: `Grid.clear` without `band.zero_()`, without `_mp.zero_()`: each fails here. Without
    `pool_owner.fill_(-1)` it passes: the same particles claim the same rows for the same fragments (equivalent
    here; it only wastes slots when a node's fragments change)."""
    sim, topo = slab(seed, device, n=1000, storage="slots")
    sim.latch(topo)
    g = sim.grid
    shadow = S.Grid(g.origin, g.dx, g.shape, device, slots=g.slots, max_fragments=sim.cfg.max_fragments)
    shadow.n_fields = 2
    shadow.ensure_pool(4096)
    out = []
    with sim._stream_scope():
        for _ in range(2):
            sim.p2g(DT, target=shadow, multifield=True)
            out.append((shadow.mass.cpu().clone(), shadow.band_mass.cpu().clone(), shadow.fragment_mass(2).cpu()))
    (m1, b1, f1), (m2, b2, f2) = out
    assert float(b1.sum()) > 0
    torch.testing.assert_close(m2, m1, rtol=1e-6, atol=1e-9)
    torch.testing.assert_close(b2, b1, rtol=1e-6, atol=1e-9)
    P = sim.particles
    want = torch.stack([P.mass.double()[P.fragment == k].sum() for k in range(2)]).cpu()
    torch.testing.assert_close(f2, want, rtol=1e-5, atol=0.0)


def _resting_block(device, v=(0.0, 0.0, 0.0)):
    g = torch.Generator().manual_seed(3)
    x, vol = block((0.31, 0.33, 0.35), (0.62, 0.6, 0.58), 1.0 / 64, jitter=0.9, generator=g)
    P = particles(x, vol, v=torch.tensor(v).expand(len(x), 3).clone(), E=1e4, nu=0.3)
    return S.Simulator(config(32, variant="baseline", dt=1e-3), P, device=device)


@pytest.mark.parametrize("speed", [0.0, 2.0])
def test_the_active_box_holds_every_stencil_the_horizon_can_reach(device, speed):
    """`fit_active_box(h)`: the particles' bounds plus the stencil (base = ⌊ξ − ½⌋ … base + 2), the travel |v| h and
    the slack. At rest (h = 0) every particle's stencil lies in the box with none to spare on the stencil's side;
    moving at 2 m/s, every particle moved by v h (3.2 Δx) still deposits inside it. P2G counts no escape.
    Bugs tried: `pad = 3 + …` as `pad = 0 + …` (the active box without the stencil's margin) and as `pad = 1 + …`;
    the travel term dropped; both fail here (a 2-node pad is equivalent: base ≥ ⌊ξ⌋ − 1 and base + 2 ≤ ⌊ξ⌋ + 2)."""
    h = 0.05
    v = (speed, -0.5 * speed, 0.3 * speed)
    sim = _resting_block(device, v)
    dx = sim.grid.dx
    sim.fit_active_box(h if speed else 0.0)
    if speed:
        sim.particles.x.add_(torch.tensor(v, device=device) * h)
    xi = (sim.particles.x.double().cpu() - torch.tensor(sim.grid.origin, dtype=torch.float64)) / dx
    base = torch.floor(xi - 0.5).long()
    lo, hi = torch.tensor(sim.slots.box[:3]), torch.tensor(sim.slots.box[3:])
    assert bool((base >= lo).all() and (base + 2 < hi).all()), (sim.slots.box, base.amin(0), base.amax(0))
    if speed:
        assert float((xi.amax(0) - xi.amin(0)).max()) > 0
    sim.counts.zero_()
    with sim._stream_scope():
        sim.p2g(1e-3)
    assert int(sim.counts[COUNT_ESCAPED]) == 0


def test_each_fragment_box_holds_every_stencil_the_horizon_can_reach(device, seed):
    """With per-fragment boxes, `fit_active_box(h)` gives each box its fragment's stencils plus 1 + ⌈travel/Δx⌉ + the
    slack nodes: the particles moved by v h afterwards (2.2 Δx) deposit without one escape.
    Bug tried: the travel term dropped from the boxes' slack (`1 + self.box_slack`): fails here."""
    sim, topo = slab(seed, device, storage="boxes")
    sim.latch(topo)
    h = 0.02
    v = torch.tensor([3.5, -2.0, 1.0], device=device)
    sim.particles.v.copy_(v.expand_as(sim.particles.v))
    with sim._stream_scope():
        sim.fit_active_box(h)
        sim.particles.x.add_(v * h)
        sim.counts.zero_()
        sim.set_clock(DT)
        sim.p2g(DT)
    assert int(sim.counts[COUNT_ESCAPED]) == 0


def test_shared_support_and_mixing_of_known_fields_in_the_slot_storage():
    """Shared support = nodes with ≥ 2 active fields (m > ε_m) over nodes with ≥ 1, in percent; the counterfactual
    mixing Σ_i Σ_k m_i^k ‖v̄_i − v_i^k‖² / Σ m equals Σ_i (1/M_i) Σ_{a<b} m_a m_b ‖v_a − v_b‖² (the pairwise form);
    Σ_i m_i^k per fragment. Three fields on a 6³ grid written straight into the slots: field 0 (slot 0) on i < 3,
    field 1 on j < 2, field 2 on l = 5, each at its own constant velocity, and field 2 with a mass below ε_m on
    l = 4 (inactive: counted in no support). Both the torch twin (`Grid.mixing`, `fragment_mass`) and the two
    launches (`Grid.field_sums`) must give these numbers.
    Bugs tried: shared nodes counted at ≥ 1 field (`active >= 2` as `>= 1`), a pool row whose slot 0 is empty not
    counted as active, the percentage without its 100, `m > ε_m` as `m >= 0`; each fails here."""
    from simutil import fill_slots

    from fracture_gs.sim.grid.fields import Grid

    s, eps = 6, 1e-9
    g = Grid((0.0, 0.0, 0.0), 1.0 / s, (s, s, s), "cpu", slots=4)
    g.ensure_pool(s**3)
    i, j, l = torch.meshgrid(*(torch.arange(s),) * 3, indexing="ij")  # noqa: E741
    m = torch.zeros(3, s, s, s, dtype=torch.float64)
    m[0][i < 3] = 1.0
    m[1][j < 2] = 2.0
    m[2][l == 5] = 0.5
    m[2][l == 4] = 1e-12  # below ε_m
    vel = torch.tensor([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -1.0]], dtype=torch.float64)
    v = vel[:, None, None, None, :].expand(3, s, s, s, 3)
    fill_slots(g, m, v)
    g.n_fields = 3
    on = m > eps
    count = on.sum(0)
    shared = 100.0 * float((count >= 2).sum()) / float((count >= 1).sum())
    M = m.sum(0)
    pair = torch.zeros(s, s, s, dtype=torch.float64)
    for a in range(3):
        for b in range(a + 1, 3):
            pair += m[a] * m[b] * on[a] * on[b] * float((vel[a] - vel[b]).square().sum())
    mixing = float((pair / M.clamp_min(1e-300)).sum() / m.sum())
    assert 0 < shared < 100 and mixing > 0.1
    cf, pct = g.mixing(eps)
    assert float(pct) == pytest.approx(shared, rel=1e-9)
    assert float(cf) == pytest.approx(mixing, rel=1e-5)
    torch.testing.assert_close(g.fragment_mass(3), m.flatten(1).sum(1), rtol=1e-6, atol=0.0)
    cf, pct, mass = g.field_sums(eps, 3)
    assert float(pct) == pytest.approx(shared, rel=1e-9)
    assert float(cf) == pytest.approx(mixing, rel=1e-5)
    torch.testing.assert_close(mass, m.flatten(1).sum(1), rtol=1e-6, atol=0.0)


def test_box_clear_empties_mass_momentum_and_band_for_the_next_deposit(device, seed):
    """`FragmentBoxes.clear` runs after every substep: the next P2G must start from empty fields, so two deposits
    with a clear between them give the fields of one: mass, momentum and the band mass of the latched gate.
    Bug tried: `box_clear` without `b.band[t] = 0.0` (the band masses grow every substep): fails here."""
    P, w = two_pieces(seed, device)
    band = (torch.arange(len(P["x"]), device=device) % 3 == 0).to(torch.int32)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), DX, device)
    boxes.fit(P["x"], P["fragment"])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=device)
    fields = []
    for _ in range(2):
        boxes.p2g(w, clock(device), wp.from_torch(counts), band_flags=wp.from_torch(band))
        fields.append((boxes.mp.cpu().clone(), boxes.band.cpu().clone()))
        boxes.clear()
    (mp1, b1), (mp2, b2) = fields
    assert float(b1.sum()) > 0
    torch.testing.assert_close(mp2, mp1, rtol=1e-6, atol=1e-9)
    torch.testing.assert_close(b2, b1, rtol=1e-6, atol=1e-9)


def test_boxes_that_share_one_node_layer_are_contact_partners(device):
    """Two boxes overlap when they share a node, a single layer included: each lists the other among its contact
    partners (`over`), so the fields that meet on that layer are projected. Fragment 0's stencils end at node 10 and
    fragment 1's start at node 10 (no slack): they share the layer x = 10 only; a third fragment far away meets
    neither.
    Bug tried: the overlap test `lo ≤ hi` as `lo < hi` (boxes touching on one layer never meet): fails here."""
    ensure_warp()
    # base = ⌊ξ − ½⌋: ξ = 8.7 → base 8, stencil 8 … 10; ξ = 10.7 → base 10, stencil 10 … 12
    x = torch.tensor([[8.7, 5.6, 5.6], [10.7, 5.6, 5.6], [18.7, 18.6, 18.6]]) * DX
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), DX, device)
    boxes.fit(x.to(device), torch.tensor([0, 1, 2], dtype=torch.int32, device=device), slack=0)
    top0 = int(boxes.lo[0, 0] + boxes.dims[0, 0] - 1)
    assert top0 == 10 and int(boxes.lo[1, 0]) == 10, "the boxes share the layer x = 10 only"
    start, over = boxes.over_start.cpu().tolist(), boxes.over.cpu().tolist()
    partners = {k: over[start[k] : start[k + 1]] for k in range(3)}
    assert partners == {0: [1], 1: [0], 2: []}
