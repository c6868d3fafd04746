"""The boxes' P2G in runs (`boxes.kernels.BOX_P2G`) built in debug mode, where Warp checks every index.

A thread sums consecutive particles in registers while they share fragment and stencil base, and flushes the run
when either changes: the new-run test compares the fragment and the three components of the stencil base with the
run's. In the release build an index past a vector's end (`cur[3]` of a 3-vector) is undefined behaviour that the
compiler may fold into anything that still passes (every particle a run of its own deposits the same), so the
kernel's own source is compiled here a second time with Warp's index checks (`mode = "debug"`, a module of its own,
a few seconds): an out-of-range component stops the process. Its deposits must still be the float64 reference's
(mass, momentum and the band particles' mass of each fragment's field), with particles sorted by stencil base so
that runs form, break at every base and fragment change, and no stencil leaves its box.
"""

from __future__ import annotations

import pytest
import torch
import warp as wp
from simutil import rel_err

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim import reference as ref
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.boxes.kernels import BOX_P2G
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS

N, n, DT = 2000, 16, 1e-3


def _debug_kernel():
    """`box_p2g_runs_band` (band masses compiled in) from its own source, in a module of its own with index checks."""
    ensure_warp()
    return wp.kernel(
        BOX_P2G[True].func, name="box_p2g_runs_band_checked", module="unique", module_options={"mode": "debug"}
    )


def _particles():
    """Particles in [0.3, 0.7]³ of a 16³ grid sorted by stencil base (x, then y, then z: consecutive particles
    mostly share the first two components and differ in the third), four fragments by quadrant, band particles
    within 1.5 Δx of x = ½; random v, C, τ."""
    g = torch.Generator().manual_seed(11)
    x = 0.3 + 0.4 * torch.rand(N, 3, generator=g)
    base = torch.floor(x * n - 0.5).long()
    x = x[torch.argsort((base[:, 0] * n + base[:, 1]) * n + base[:, 2])].contiguous()
    tau = torch.randn(N, 3, 3, generator=g)
    return {
        "x": x,
        "v": torch.randn(N, 3, generator=g),
        "C": torch.randn(N, 3, 3, generator=g),
        "mass": 0.5 + torch.rand(N, generator=g),
        "volume": (0.5 + torch.rand(N, generator=g)) * 1e-4,
        "stress": tau + tau.transpose(1, 2),
        "fragment": ((x[:, 0] > 0.5).int() + 2 * (x[:, 1] > 0.5).int()).to(torch.int32),
        "band": ((x[:, 0] - 0.5).abs() < 1.5 / n).to(torch.int32),
    }


@pytest.mark.parametrize("run", [1, 8])
def test_runs_of_a_checked_build_deposit_the_reference_fields(run):
    """One particle a thread and runs of 8 (most particles continue a run; hundreds of runs end where only the base's
    z component changes): every index the kernel reads or writes is in range (a debug build
    aborts otherwise), no stencil escapes, and each fragment's box holds the reference's mass, momentum and band
    mass (relative error ≤ 1e-5)."""
    P = _particles()
    base = torch.floor(P["x"].double() * n - 0.5).long()
    same = (base[1:] == base[:-1]).all(1)
    z_only = (base[1:, :2] == base[:-1, :2]).all(1) & ~same
    assert int(same.sum()) > N // 2, "most particles continue their neighbour's run"
    assert int(z_only.sum()) > 200, "hundreds of runs end where only the stencil's z changes"
    kernel = _debug_kernel()
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, "cpu")
    boxes.fit(P["x"], P["fragment"])
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t, dtype=types.get(k)) for k, t in P.items()}
    arrays = [w[k] for k in ("x", "v", "C", "mass", "volume", "stress", "fragment")]
    inputs = arrays + [clock.view, boxes.view, run, wp.from_torch(counts), w["band"]]
    wp.launch(kernel, dim=-(-N // run), inputs=inputs, device="cpu")
    wp.synchronize_device("cpu")
    assert int(counts[COUNT_ESCAPED]) == 0
    gm, gp, gb = ref.p2g(
        P["x"], P["v"], P["C"], P["mass"], P["volume"], P["stress"], P["fragment"], 4, (n, n, n),
        (0.0, 0.0, 0.0), 1.0 / n, DT, band=P["band"],
    )  # fmt: skip
    assert float(gb.sum()) > 0, "band particles deposit band mass"
    for k in range(4):
        lo, d = [int(v) for v in boxes.lo[k]], [int(v) for v in boxes.dims[k]]
        region = (slice(lo[0], lo[0] + d[0]), slice(lo[1], lo[1] + d[1]), slice(lo[2], lo[2] + d[2]))
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        m, p, _ = boxes.field(k)
        band = boxes.band[a:b].reshape(d)
        assert float(gm[k][region].sum()) == pytest.approx(float(gm[k].sum()), rel=1e-12), "the box holds it all"
        assert rel_err(m, gm[k][region]) <= 1e-5, f"mass of field {k}"
        assert rel_err(p, gp[k][region]) <= 1e-5, f"momentum of field {k}"
        assert rel_err(band, gb[k][region]) <= 1e-5, f"band mass of field {k}"
