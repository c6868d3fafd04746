"""G2P's fan-out (`sim.grid.fanout_kernels.g2p_fanout`) gives each listed particle one warp of LANES = 32
threads. Exactly one lane — lane 0 — writes the particle, once, whatever the mode:

- `coop` = 0 (the CPU): lane 0 gathers all 27 stencil nodes alone and lanes 1 … 31 return at once;
- `coop` = 1 (CUDA): lane q < 27 loads stencil node q, the lanes' terms are summed by `lane_sum`, and lane 0 alone
  writes the sum. On the CPU `lane_sum` is the identity (no shuffles), so there lane 0 writes its own node's
  term only: the weight of node (0, 0, 0) times that node's velocity — which shows which lane wrote, and that
  one did;
- (the cooperative loads' lane bound, 27 = 3³, is observable only through CUDA's shuffles: a GPU test's job.)

One particle of fragment 0 on an 8³ grid (Δx = 1/8) whose slot 0 belongs to fragment 0 and moves at u everywhere;
the particle sits half a cell above its stencil base, f = (0.5, 0.5, 0.5), where node (0, 0, 0)'s weight is
(½ (1.5 − 0.5)²)³ = 1/8. Its new position is clamped on x, so each write counts one clamp."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fanout_kernels import LANES, g2p_fanout
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.storage import COUNT_CLAMPED, N_COUNTS

ensure_warp()
DX, DT = 1 / 8, 1e-3
U = (1.0, -2.0, 0.5)
X0 = (3.5 * DX, 3.5 * DX, 3.5 * DX)  # stencil base 3, f = 0.5 on every axis


def _gather(coop):
    """(v, clamped count) of the one listed particle after one fan-out G2P launch (v preset to 7)."""
    g = Grid((0.0, 0.0, 0.0), DX, (8, 8, 8), "cpu")
    g._owner.fill_(1)
    g._vel.copy_(torch.tensor(U).expand(g._vel.shape[0], 3))
    x = torch.tensor([X0])
    v, C, F = torch.full((1, 3), 7.0), torch.zeros(1, 3, 3), torch.eye(3).repeat(1, 1, 1)
    one = lambda *a: wp.from_torch(torch.tensor(a, dtype=torch.int32))  # noqa: E731
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    inputs = [wp.from_torch(x, dtype=wp.vec3), wp.from_torch(v, dtype=wp.vec3), wp.from_torch(C, dtype=wp.mat33)]
    inputs += [wp.from_torch(F, dtype=wp.mat33), one(0), one(0), one(1), wp.zeros(27, dtype=wp.int32, device="cpu")]
    inputs += [0, coop, clock.view, g.view, wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.25, 1.0, 1.0)]  # x clamped to 0.25
    inputs += [wp.from_torch(counts), one(0), 0]
    wp.launch(g2p_fanout, dim=LANES, inputs=inputs, device="cpu")
    return v[0], int(counts[COUNT_CLAMPED])


def test_lane_zero_alone_writes_the_whole_gather_on_the_cpu():
    """coop = 0: the particle takes u (the 27 weights sum to 1) and one clamp is counted — one writer, not 32."""
    v, clamped = _gather(0)
    torch.testing.assert_close(v, torch.tensor(U), rtol=0, atol=1e-6)
    assert clamped == 1


def test_in_the_cooperative_launch_lane_zero_alone_writes_after_the_sums():
    """coop = 1 on the CPU (lane_sum = identity): the particle is written once (one clamp counted), by lane 0, with
    node (0, 0, 0)'s term w u = u / 8 — not left unwritten, and not overwritten by another lane's node."""
    v, clamped = _gather(1)
    torch.testing.assert_close(v, torch.tensor(U) / 8, rtol=0, atol=1e-7)
    assert clamped == 1
