"""Per-fragment boxes fitted tight (`FragmentBoxes.fit(slack=0)`: box k is exactly the range of fragment k's
stencil nodes, so particles sit on every face of their box and the first box starts at buffer index 0).

- `box_kernels.box_g2p` (with `stencil_inside`): every particle whose 27 nodes lie in its own box gathers its own
  fragment's field, and a quadratic B-spline reproduces an affine field exactly: v_p = u_k + A x_p, C_p = A,
  F ← (I + Δt A) F, x ← x + Δt v_p, the particles at the box's lowest and highest corners included; a stencil
  one node past either face is left alone (P2G counts it as an escape).
- `box_kernels.box_mass_gradient`: the central difference of the box's nodal masses, zero beyond the box, where
  the box's faces hold mass (with slack they are empty, and a wrong neighbour there reads zero either way).

Closed forms and torch's own central differences, 12³ and 16³ grids on the CPU."""

import torch
import warp as wp
from simutil import box_gradient, zero_padded_gradient

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.storage import N_COUNTS

DT = 1e-3


def _floor_base(x, dx):
    return torch.floor(x.double() / dx - 0.5).long()  # [N, 3] stencil base (origin 0)


def _gather_state():
    """Two fragments of a jittered lattice in [0.3, 0.7]³ on a 12³ grid (x < ½: fragment 0), plus twelve probe
    particles appended after the fit: for each fragment and axis one whose stencil base is one node below its
    box's lowest node along that axis, and one whose stencil ends one node above its box's highest node.
    Returns (x [N+12, 3], fragment, boxes fitted to the first N, N, grid nodes per axis)."""
    ensure_warp()
    n = 12
    dx = 1.0 / n
    g = torch.Generator().manual_seed(5)
    ax = torch.arange(0.3 + 0.025, 0.7, 0.05, dtype=torch.float64)
    x = torch.stack(torch.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    x = (x + (torch.rand(x.shape, generator=g, dtype=torch.float64) - 0.5) * 0.02).float()
    fragment = (x[:, 0] >= 0.5).to(torch.int32)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), dx, "cpu")
    boxes.fit(x, fragment, slack=0)
    probes, frags = [], []
    for k in range(2):
        lo = boxes.lo[k].long()
        hi = lo + boxes.dims[k].long() - 1  # the box's highest node = the highest stencil base + 2
        for a in range(3):
            below = lo.clone()
            below[a] -= 1  # base one node below the box along axis a
            above = hi - 2
            above[a] += 1  # the stencil's top one node above the box along axis a
            for base in (below, above):
                probes.append((base.double() + 1.0) * dx)  # ξ = base + 1: ⌊ξ − ½⌋ = base
                frags.append(k)
    x = torch.cat([x, torch.stack(probes).float()])
    fragment = torch.cat([fragment, torch.tensor(frags, dtype=torch.int32)])
    return x, fragment, boxes, len(x) - len(probes), n


def test_tight_box_g2p_reproduces_each_fragments_affine_field_at_every_particle():
    """Box k's nodes carry v_i = u_k + A x_i (u_0 ≠ u_1). G2P of every fitted particle, the corner particles whose
    stencil starts at box 0's first buffer index or ends at a box's last node included, gives exactly its own
    fragment's affine field: v_p = u_k + A x_p, C_p = A, F_p = (I + Δt A) F_p⁰, x_p ← x_p + Δt v_p (float32
    rounding). A probe particle whose stencil lies one node outside its box, below or above along any axis, keeps
    x, v, C, F."""
    x, fragment, boxes, N, n = _gather_state()
    dx = 1.0 / n
    base = _floor_base(x[:N], dx)
    for k in range(2):  # the fit is tight: some particle's stencil starts at lo and one ends at the box's top
        mine = fragment[:N] == k
        lo, top = boxes.lo[k].long(), boxes.lo[k].long() + boxes.dims[k].long() - 3
        assert bool((base[mine] == lo).all(1).any()), f"a particle of fragment {k} at its box's lowest corner"
        assert bool((base[mine] == top).all(1).any()), f"a particle of fragment {k} at its box's highest corner"
    assert int(boxes.offset[0]) == 0
    u = torch.tensor([[0.3, -0.2, 0.5], [-0.4, 0.1, 0.2]], dtype=torch.float64)
    A = torch.tensor([[0.5, -1.0, 0.25], [0.75, -0.5, 1.0], [-0.25, 0.5, 0.4]], dtype=torch.float64)
    for k in range(2):
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        d = [int(s) for s in boxes.dims[k]]
        nodes = boxes.lo[k].long() + torch.stack(
            torch.meshgrid(*[torch.arange(s) for s in d], indexing="ij"), -1
        ).reshape(-1, 3)
        boxes.vel[a:b] = (u[k] + (nodes.double() * dx) @ A.T).float()
    M = len(x)
    g = torch.Generator().manual_seed(6)
    v0 = torch.randn(M, 3, generator=g)
    C0 = torch.randn(M, 3, 3, generator=g)
    F0 = torch.eye(3) + 0.1 * torch.randn(M, 3, 3, generator=g)
    state = {"x": x.clone(), "v": v0.clone(), "C": C0.clone(), "F": F0.clone(), "fragment": fragment}
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "F": wp.mat33}
    w = {key: wp.from_torch(t, dtype=types.get(key)) for key, t in state.items()}
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    boxes.g2p(w, clock.view, wp.vec3(0.0, 0.0, 0.0), wp.vec3(1.0, 1.0, 1.0), wp.from_torch(counts))
    xd = x[:N].double()
    want_v = u[fragment[:N].long()] + xd @ A.T
    torch.testing.assert_close(state["v"][:N].double(), want_v, rtol=0, atol=2e-6)
    torch.testing.assert_close(state["C"][:N].double(), A.expand(N, 3, 3), rtol=0, atol=2e-5)
    want_F = (torch.eye(3, dtype=torch.float64) + DT * A) @ F0[:N].double()
    torch.testing.assert_close(state["F"][:N].double(), want_F, rtol=0, atol=2e-6)
    torch.testing.assert_close(state["x"][:N].double(), xd + DT * want_v, rtol=0, atol=1e-6)
    for key, before in (("x", x), ("v", v0), ("C", C0), ("F", F0)):
        assert torch.equal(state[key][N:], before[N:]), f"a stencil outside its box changed {key}"


def test_mass_gradient_of_a_tight_box_reads_zero_beyond_every_face():
    """Boxes fitted tight (no empty layer) to two fragments of random particles deposited by P2G hold mass on all
    six faces; ∇m^k at every node of each box is still (m[i+1] − m[i−1]) / 2Δx per axis with a node beyond the
    box counting as massless, not as the neighbouring row's, box's or buffer's mass."""
    from fracture_gs.sim.storage import N_COUNTS as NC

    ensure_warp()
    n, N = 16, 3000
    gen = torch.Generator().manual_seed(7)
    x = 0.25 + 0.5 * torch.rand(N, 3, generator=gen)
    fragment = (x[:, 2] >= 0.5).to(torch.int32)  # split along z: box 1 follows box 0 in the buffer
    P = {
        "x": x,
        "v": torch.zeros(N, 3),
        "C": torch.zeros(N, 3, 3),
        "mass": 0.5 + torch.rand(N, generator=gen),
        "volume": torch.full((N,), 1e-5),
        "stress": torch.zeros(N, 3, 3),
        "fragment": fragment,
    }
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = {key: wp.from_torch(t.contiguous(), dtype=types.get(key)) for key, t in P.items()}
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, "cpu")
    boxes.fit(x, fragment, slack=0)
    boxes.p2g(w, clock.view, wp.from_torch(torch.zeros(NC, dtype=torch.int32)))
    for k in range(2):
        d = [int(v) for v in boxes.dims[k]]
        a = int(boxes.offset[k])
        m = boxes.mp[a : a + d[0] * d[1] * d[2], 3].double().reshape(d)
        for face in (m[0], m[-1], m[:, 0], m[:, -1], m[:, :, 0], m[:, :, -1]):
            assert float(face.sum()) > 1e-3 * float(m.sum()), "every face of a tight box holds mass"
        want = zero_padded_gradient(m, n)
        got = box_gradient(boxes, k)
        assert float((got - want).abs().max()) < 1e-5 * float(want.abs().max()), f"box {k}"
