"""P2G in runs (`run_kernels.p2g_runs`) on a single-field grid, launched directly: the deposits equal the float64
reference's (Eq. multifield_p2g with one field: m_i = Σ_p w_ip m_p, p_i = Σ_p w_ip m_p (v_p + C_p(x_i − x_p)) −
Δt V⁰ τ_p ∇w_ip) at every node; a run reaches exactly the 27 nodes of its stencil, so every node outside all
stencils keeps the −0.0 it was given (adding even +0.0 turns it into +0.0); and a particle whose stencil leaves
the active range [lo, hi) is counted once as an escape, at either end of every axis. The run's sums and flush
(`add_particle`, `flush_run`) also run in a debug build of a kernel in this file, where Warp checks every index:
rows of the 27 × 4 sums past 26 are undefined behaviour that the release build may silently drop."""

import torch
import warp as wp
from simutil import block

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim import reference as ref
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import GridView
from fracture_gs.sim.grid.run_kernels import flush_run, p2g_runs
from fracture_gs.sim.stencil import add_particle, stencil, stencil_sums
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS

wp.set_module_options({"mode": "debug"})  # this file's own kernel only (`_one_run`): index checks compiled in

N_GRID = 16
DX = 1.0 / N_GRID
DT = 1e-3


def _particles():
    """A jittered lattice of two particles per cell in [0.3, 0.6]³, sorted by stencil base (runs of one base),
    random v, C and τ."""
    g = torch.Generator().manual_seed(4)
    x, vol = block((0.3, 0.3, 0.3), (0.6, 0.6, 0.6), DX / 2, jitter=0.8, generator=g)
    base = torch.floor(x.double() / DX - 0.5).long()
    key = (base[:, 0] * N_GRID + base[:, 1]) * N_GRID + base[:, 2]
    x = x[torch.argsort(key, stable=True)].contiguous()
    n = len(x)
    return {
        "x": x,
        "v": torch.randn(n, 3, generator=g),
        "C": torch.randn(n, 3, 3, generator=g),
        "mass": 0.5 + torch.rand(n, generator=g),
        "volume": torch.full((n,), vol),
        "stress": 100.0 * torch.randn(n, 3, 3, generator=g),
    }


def _launch(P, run, lo, hi):
    """Grid (its buffer filled with −0.0 first) and counters after one `p2g_runs` launch."""
    ensure_warp()
    grid = Grid((0.0, 0.0, 0.0), DX, (N_GRID,) * 3, "cpu")
    grid._mp.fill_(-0.0)
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "stress": wp.mat33}
    w = [wp.from_torch(P[k], dtype=types.get(k)) for k in ("x", "v", "C", "mass", "volume", "stress")]
    solo = wp.from_torch(torch.ones(len(P["x"]), dtype=torch.int32))
    n = len(P["x"])
    inputs = w + [solo, 0, run, clock.view, grid.view, wp.vec3i(*lo), wp.vec3i(*hi), wp.from_torch(counts)]
    wp.launch(p2g_runs, dim=-(-n // run), inputs=inputs, device="cpu")
    return grid, counts


def test_runs_deposit_the_reference_fields_into_their_stencils_only():
    """Runs of 1, 4 and 7 particles: mass and momentum at every node within float32 rounding of the float64
    reference P2G; nodes no particle's stencil reaches keep −0.0 (not even +0.0 was added); the runs merge many
    particles (most share their predecessor's base); none escapes the whole grid."""
    P = _particles()
    base = torch.floor(P["x"].double() / DX - 0.5).long()
    assert int((base[1:] == base[:-1]).all(1).sum()) > len(base) // 3, "runs merge particles of one base"
    shape = (N_GRID,) * 3
    field = torch.zeros(len(P["x"]), dtype=torch.long)
    gm, gp, _ = ref.p2g(
        P["x"], P["v"], P["C"], P["mass"], P["volume"], P["stress"], field, 1, shape, (0.0, 0.0, 0.0), DX, DT
    )
    want = torch.cat([gp[0].reshape(-1, 3), gm[0].reshape(-1, 1)], 1)  # [nodes, 4]
    off = torch.stack(torch.meshgrid(*[torch.arange(3)] * 3, indexing="ij"), -1).reshape(27, 3)
    nodes = (base[:, None, :] + off[None]).reshape(-1, 3)
    reached = torch.zeros(shape, dtype=torch.bool)
    reached[nodes[:, 0], nodes[:, 1], nodes[:, 2]] = True
    reached = reached.reshape(-1)
    assert 0 < int(reached.sum()) < reached.numel() // 2
    for run in (1, 4, 7):
        grid, counts = _launch(P, run, (0, 0, 0), shape)
        got = grid._mp.double()
        assert int(counts[COUNT_ESCAPED]) == 0
        scale = want.abs().amax(0)  # [4]
        assert bool(((got - want).abs() <= 2e-5 * scale).all()), f"run {run}: deposits"
        assert bool(torch.signbit(grid._mp[~reached]).all()), f"run {run}: a node outside every stencil was written"
        assert not bool(torch.signbit(grid._mp[reached, 3]).any()), f"run {run}: every stencil node was written"


def test_runs_count_each_stencil_that_leaves_the_active_range():
    """With the active range [lo, hi) shrunk by one node at both ends of every axis past the particles' stencils
    (lo one above the lowest stencil base, hi one below the highest stencil node + 1), the escapes counted are
    exactly the particles whose stencil base lies below lo or whose stencil's top node lies at or above hi on
    some axis, whatever the run length."""
    P = _particles()
    base = torch.floor(P["x"].double() / DX - 0.5).long()
    lo = base.amin(0) + 1
    hi = base.amax(0) + 2  # the highest stencil node is base + 2: it lies outside [lo, hi)
    out = ((base < lo) | (base + 2 >= hi)).any(1)
    assert 0 < int(out.sum()) < len(base)
    for run in (1, 4):
        _, counts = _launch(P, run, tuple(lo.tolist()), tuple(hi.tolist()))
        assert int(counts[COUNT_ESCAPED]) == int(out.sum()), f"run {run}"
    _, counts = _launch(P, 4, tuple((lo - 1).tolist()), tuple((hi + 1).tolist()))
    assert int(counts[COUNT_ESCAPED]) == 0, "stencils touching lo and hi − 1 lie inside"


@wp.kernel
def _one_run(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    mass: wp.array(dtype=float),
    force: wp.array(dtype=wp.mat33),
    g: GridView,
):
    """All particles' deposits summed in registers (`add_particle`) and flushed once (`flush_run`) at the first
    particle's stencil base, in a debug build that checks every matrix row and array index."""
    acc = stencil_sums()
    base = wp.vec3i(0, 0, 0)
    for p in range(x.shape[0]):
        b, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
        base = b
        acc = add_particle(acc, f, w, dw, g.dx, g.inv_dx, mass[p], v[p], C[p], force[p])
    flush_run(g, base, acc)


def test_a_run_sums_and_flushes_within_its_27_nodes_in_a_debug_build():
    """Particles of one stencil base summed by `add_particle` and added by `flush_run`, compiled with Warp's index
    checks (an out-of-range row of the 27 × 4 sums or an index past the grid stops the process): the 27 stencil
    nodes hold the float64 reference's mass and momentum, every other node keeps its −0.0."""
    P = _particles()
    base = torch.floor(P["x"].double() / DX - 0.5).long()
    one = (base == base[len(base) // 2]).all(1)
    assert int(one.sum()) >= 2, "particles sharing one stencil base"
    Q = {k: t[one].contiguous() for k, t in P.items()}
    force = -DT * Q["volume"][:, None, None] * Q["stress"]
    grid = Grid((0.0, 0.0, 0.0), DX, (N_GRID,) * 3, "cpu")
    grid._mp.fill_(-0.0)
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33}
    w = [wp.from_torch(Q[k], dtype=types.get(k)) for k in ("x", "v", "C", "mass")]
    wp.launch(_one_run, dim=1, inputs=w + [wp.from_torch(force.contiguous(), dtype=wp.mat33), grid.view], device="cpu")
    field = torch.zeros(len(Q["x"]), dtype=torch.long)
    shape = (N_GRID,) * 3
    origin = (0.0, 0.0, 0.0)
    gm, gp, _ = ref.p2g(Q["x"], Q["v"], Q["C"], Q["mass"], Q["volume"], Q["stress"], field, 1, shape, origin, DX, DT)
    want = torch.cat([gp[0].reshape(-1, 3), gm[0].reshape(-1, 1)], 1)
    reached = (gm[0] > 0).reshape(-1)
    assert int(reached.sum()) == 27
    got = grid._mp.double()
    assert bool(((got[reached] - want[reached]).abs() <= 2e-5 * want.abs().amax(0)).all())
    assert bool(torch.signbit(grid._mp[~reached]).all()), "a node outside the stencil was written"
