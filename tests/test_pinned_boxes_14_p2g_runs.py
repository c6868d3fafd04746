"""The boxes' P2G in runs (`boxes.kernels.BOX_P2G`): where one run ends and the next begins.

A thread sums consecutive particles in registers while they share fragment and stencil base and adds the sums to
the run's box once. A run must end when the fragment changes at the same base, and when exactly one component of
the base changes, whichever it is. The particles here walk from a diagonal base D = (c, c, c) one node up along
x, back to D, up along y, back, up along z, back (so a new-run test that compares a base component with the wrong
component of the run's base misses a change, either going out or coming back), and switch fragment at D. A stencil
that leaves its box in the middle of a thread's particles is counted once per particle and deposits nothing, and
the run after it deposits normally. The last run of the sequence starts at buffer index 0 (box 0's lowest node,
the tight box's first corner) and must still be added when the thread ends. Box 0's three dims differ, so a
band-mass index taken with the wrong dim shows. Every deposit (mass, momentum with the stress term, band mass) is
checked against the float64 reference `reference.p2g`, with the grid's origin off zero, for one particle a
thread, runs of 4 and one thread for all.
"""

import pytest
import torch
import warp as wp
from simutil import rel_err

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim import reference as ref
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS

n, DX, DT = 16, 1.0 / 16, 1e-3
ORIGIN = (0.1, -0.2, 0.05)
D = (6, 6, 6)


def _walk():
    """(base, fragment, probe) per group of three particles: the walk described above, box 0 widened first by
    groups at D + (2, 0, 0) and D + (0, 0, 3) (dims 5, 4, 6 with slack 0), and two probe particles of fragment 1
    whose stencil ends one node above box 1 along y (not in the fit)."""
    e = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    up = lambda a: tuple(D[i] + e[a][i] for i in range(3))  # noqa: E731
    groups = [((8, 6, 6), 0, False), ((6, 6, 9), 0, False)]
    for frag in (0, 1):
        for a in range(3):
            groups += [(D, frag, False), (up(a), frag, False)]
        groups += [(D, frag, False), (D, 1 - frag, False)]
    groups += [((6, 8, 6), 1, True), (D, 1, False), (D, 0, False)]  # probes, then the run after them, then box 0's
    return groups  # last run: its stencil starts at buffer index 0


def _particles():
    g = torch.Generator().manual_seed(1414)
    rows = []
    for base, frag, probe in _walk():
        for _ in range(2 if probe else 3):
            u = 0.1 + 0.8 * torch.rand(3, generator=g, dtype=torch.float64)  # ξ − base ∈ [0.6, 1.4]: ⌊ξ − ½⌋ = base
            rows.append((torch.tensor(base, dtype=torch.float64) + 0.5 + u, frag, probe))
    xi = torch.stack([r[0] for r in rows])
    x = (torch.tensor(ORIGIN, dtype=torch.float64) + xi * DX).float()
    M = len(x)
    tau = torch.randn(M, 3, 3, generator=g)
    P = {
        "x": x,
        "v": torch.randn(M, 3, generator=g),
        "C": torch.randn(M, 3, 3, generator=g),
        "mass": 0.5 + torch.rand(M, generator=g),
        "volume": (0.5 + torch.rand(M, generator=g)) * 1e-4,
        "stress": 2000.0 * (tau + tau.transpose(1, 2)),  # Δt V⁰ τ ∇w: a few per cent of m v at a node
        "fragment": torch.tensor([r[1] for r in rows], dtype=torch.int32),
        "band": (torch.arange(M) % 2).to(torch.int32),
    }
    probe = torch.tensor([r[2] for r in rows])
    return P, probe


@pytest.mark.parametrize("band", [False, True])
@pytest.mark.parametrize("run", [1, 4, 0])
def test_runs_break_on_every_base_component_and_fragment_and_flush_at_index_zero(run, band):
    """Box k's mass, momentum (v, C and the −Δt V⁰ τ ∇w term) and, with the band build, band mass are the float64
    reference's deposits of fragment k's fitted particles (relative error ≤ 1e-5), for one particle a thread, runs
    of 4 and one thread for all (run 0 here); the two probes are the only escapes (one count each) and deposit
    nothing. The scene is what makes this a test of the run logic: see the module docstring."""
    ensure_warp()
    P, probe = _particles()
    M = len(P["x"])
    run = run or M
    base = torch.floor((P["x"].double() - torch.tensor(ORIGIN, dtype=torch.float64)) / DX - 0.5).long()
    want_base = torch.tensor([b for b, _, p in _walk() for _ in range(2 if p else 3)])
    assert torch.equal(base, want_base), "every particle's stencil base is the walk's"
    boxes = FragmentBoxes((n, n, n), ORIGIN, DX, "cpu")
    boxes.fit(P["x"][~probe], P["fragment"][~probe], slack=0)
    assert boxes.lo[0].tolist() == list(D) and boxes.dims[0].tolist() == [5, 4, 6], "box 0: lo D, three dims"
    assert int(boxes.offset[0]) == 0
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t.contiguous(), dtype=types.get(k)) for k, t in P.items()}
    boxes.p2g(w, clock.view, wp.from_torch(counts), run=run, band_flags=w["band"] if band else None)
    assert int(counts[COUNT_ESCAPED]) == int(probe.sum()) == 2, "each probe particle counted once"
    keep = ~probe
    gm, gp, gb = ref.p2g(
        P["x"][keep], P["v"][keep], P["C"][keep], P["mass"][keep], P["volume"][keep], P["stress"][keep],
        P["fragment"][keep], 2, (n, n, n), ORIGIN, DX, DT, band=P["band"][keep],
    )  # fmt: skip
    assert float(gb.sum()) > 0
    for k in range(2):
        lo, d = [int(v) for v in boxes.lo[k]], [int(v) for v in boxes.dims[k]]
        region = (slice(lo[0], lo[0] + d[0]), slice(lo[1], lo[1] + d[1]), slice(lo[2], lo[2] + d[2]))
        assert float(gm[k][region].sum()) == pytest.approx(float(gm[k].sum()), rel=1e-12), "the box holds it all"
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        m, p, _ = boxes.field(k)
        assert rel_err(m, gm[k][region]) <= 1e-5, f"mass of field {k}"
        assert rel_err(p, gp[k][region]) <= 1e-5, f"momentum of field {k}"
        got_band = boxes.band[a:b].reshape(d)
        if band:
            assert rel_err(got_band, gb[k][region]) <= 1e-5, f"band mass of field {k}"
        else:
            assert float(got_band.abs().max()) == 0.0, "the plain build adds no band mass"
    rest = boxes.mp[boxes.nodes :]  # the buffer's capacity past the last box
    assert rest.numel() == 0 or float(rest.abs().max()) == 0.0, "nothing lands past the boxes"
