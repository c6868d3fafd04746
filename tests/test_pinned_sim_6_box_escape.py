"""The per-fragment boxes' P2G (`boxes.kernels.box_p2g_runs`) deposits a particle only when all 27 nodes of its
stencil lie in its own fragment's box: a stencil whose base lies one node below the box, or whose top node lies one
node above it, along any one of the three axes, is counted once as an escape (the frame is then redone with larger
boxes) and deposits nothing, while every particle of the tight fit lands whole in its own box. Both the stencil's
lower corner and its upper corner (base + (2, 2, 2)) are checked, on every axis, one particle a thread and in runs
of consecutive particles. Tight boxes (slack 0) on a 12³ grid, twelve probe particles, on the CPU."""

import pytest
import torch
import warp as wp
from test_pinned_sim_3_k_boxes import _gather_state

from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS


@pytest.mark.parametrize("run", [1, 8])
def test_a_stencil_one_node_past_any_face_of_its_box_escapes_and_deposits_nothing(run):
    """Twelve probes (per fragment and axis, one stencil one node below the box and one one node above it) are
    exactly the escapes: 12 counted, and each box holds exactly the mass (and, at rest without stress, zero
    momentum) of its own fitted particles. A check that skipped one axis of either corner would let that probe
    deposit into a wrong node of the buffer and count one escape fewer."""
    x, fragment, boxes, N, n = _gather_state()
    M = len(x)
    g = torch.Generator().manual_seed(11)
    mass = 0.5 + torch.rand(M, generator=g)
    P = {
        "x": x.contiguous(),
        "v": torch.zeros(M, 3),
        "C": torch.zeros(M, 3, 3),
        "mass": mass,
        "volume": torch.full((M,), 1e-6),
        "stress": torch.zeros(M, 3, 3),
        "fragment": fragment,
    }
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t, dtype=types.get(k)) for k, t in P.items()}
    clock = FrameClock("cpu", 0)
    clock.set(1e-3, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    boxes.p2g(w, clock.view, wp.from_torch(counts), run=run)
    assert int(counts[COUNT_ESCAPED]) == M - N == 12, "each probe counted once, no fitted particle"
    for k in range(2):
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        want = float(mass[:N][fragment[:N] == k].double().sum())
        got = float(boxes.mp[a:b, 3].double().sum())
        assert got == pytest.approx(want, rel=1e-5), f"box {k} holds its fitted particles' mass only"
        assert float(boxes.mp[a:b, :3].abs().max()) == 0.0, f"box {k}: particles at rest deposit no momentum"
