"""The boxes' grid update (`boxes.kernels.box_grid_update`) loads a leader's partner masses four list entries at
a time (`four_partners`); entries past the end of box k's overlap list are padding and must never name a field.
Buffer index 0 — box 0's lowest node — is a real field, so padding that pointed at index 0 would read its mass
as a partner at every node of every box.

Two tight boxes (slack 0) of two overlapping slabs: each box has ONE partner, so three of the four loaded entries
are padding at every node. With the contact gate closed (fill mass ∞) every field follows the plain rule: v = p/m
+ Δt g where m > ε_m, v = 0 where 0 < m ≤ ε_m, no write where m = 0 — index 0 holding a live mass, and no slot
overflow with two fields a node."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.storage import COUNT_SLOT_OVERFLOW, N_COUNTS

n, DX, DT, EPS_M = 12, 1.0 / 12, 2e-3, 1e-6
GRAVITY = (0.5, -2.0, -9.8)
SENTINEL = 7.0


def _boxes(seed):
    """Slab 0 at x ∈ [0.25, 0.5], slab 1 at x ∈ [0.45, 0.75] (y, z ∈ [0.3, 0.6]): the boxes overlap in a few
    x-layers and each reaches nodes the other does not. Buffer masses: 0 (a fifth), ε_m / 2 (a tenth), ε_m (a
    tenth), else [0.5, 1.5]·10⁻³ kg; index 0 gets 10⁻³ kg."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    ax = torch.arange(0.3, 0.6, 0.5 * DX)
    x0 = torch.stack(torch.meshgrid(torch.arange(0.25, 0.5, 0.5 * DX), ax, ax, indexing="ij"), -1).reshape(-1, 3)
    x1 = torch.stack(torch.meshgrid(torch.arange(0.45, 0.75, 0.5 * DX), ax, ax, indexing="ij"), -1).reshape(-1, 3)
    x = torch.cat([x0, x1])
    fragment = torch.cat([torch.zeros(len(x0)), torch.ones(len(x1))]).to(torch.int32)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), DX, "cpu", max_fragments=4)
    boxes.fit(x, fragment, slack=0)
    assert boxes.K == 2 and boxes.over_start[:3].tolist() == [0, 1, 2], "one partner each"
    N = boxes.nodes
    u = torch.rand(N, generator=g)
    live = 1e-3 * (0.5 + torch.rand(N, generator=g))
    m = torch.where(u < 0.2, 0.0, torch.where(u < 0.3, 0.5 * EPS_M, torch.where(u < 0.4, EPS_M, live)))
    m[0] = 1e-3
    boxes.mp[:N, 3] = m
    boxes.mp[:N, :3] = 1e-3 * torch.randn(N, 3, generator=g)
    boxes.vel.fill_(SENTINEL)
    return boxes


def test_overlap_list_padding_never_reads_buffer_index_zero_as_a_partner():
    """Every buffer index of both boxes takes the plain rule (float32 rounding) and no slot overflow is counted,
    although index 0 holds 10⁻³ kg; nodes that only box 1 reaches are written too (box 1's threads lead there)."""
    boxes = _boxes(150)
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    walls = Boundaries([], "cpu", (n, n, n), 0)
    centroids = wp.zeros(2, dtype=wp.vec3, device="cpu")
    boxes.update(clock.view, EPS_M, GRAVITY, float("inf"), centroids, wp.from_torch(counts), walls.colliders,
                 mass_gradient=True, slots=2)  # fmt: skip
    N = boxes.nodes
    mp = boxes.mp[:N].double()
    m = mp[:, 3]
    eps = float(torch.tensor(EPS_M, dtype=torch.float32))
    want = torch.full((N, 3), SENTINEL, dtype=torch.float64)
    want[(m > 0) & (m <= eps)] = 0.0
    live = m > eps
    v = mp[:, :3] / m.clamp_min(1e-30)[:, None] + DT * torch.tensor(GRAVITY, dtype=torch.float64)
    want[live] = v[live]
    got = boxes.vel[:N].double()
    err = (got - want).abs().max(1).values / want.abs().max(1).values.clamp_min(1.0)
    assert float(err.max()) < 1e-5, f"worst buffer index {int(err.argmax())} of {N}"
    assert int(live[int(boxes.offset[1]) :].sum()) > 20, "box 1 has live fields"
    assert int(counts[COUNT_SLOT_OVERFLOW]) == 0
