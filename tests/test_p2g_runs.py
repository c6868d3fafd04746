"""P2G in runs (`grid.run_kernels.p2g_runs`, DESIGN.md "Performance rules"): a thread deposits a run of consecutive
particles and sums in registers those that share a cell, so particles sorted by cell reach each node with one
reduction per run and cell. Only the order of the float32 sums changes; with runs of one particle, nothing."""

from dataclasses import replace

import pytest
import torch
from simutil import rel_err
from test_transfer_launch import slab

from fracture_gs import sim as S
from fracture_gs.sim.storage import COUNT_ESCAPED


def one_p2g(sim, run: int):
    """The grid after one P2G of the current state ([nodes + pool, 4] float64) and the counters."""
    sim.options = replace(sim.options, p2g_run=run)
    sim.grid.reset_claims()
    sim.counts.zero_()
    sim.compute_stress(sim.stress, commit=False)
    sim.p2g(1e-3)
    return sim.grid._mp.cpu().double(), sim.counts.cpu().clone()


def shared_cells(sim, run: int) -> int:
    """Particles whose predecessor in the same run has the same stencil base (their sums merge)."""
    g = sim.grid
    base = torch.floor((sim.particles.x.cpu() - torch.tensor(g.origin)) / g.dx - 0.5).long()  # [N, 3]
    same = (base[1:] == base[:-1]).all(1)
    same &= torch.arange(1, len(base)) % run != 0
    return int(same.sum())


@pytest.mark.parametrize("order", ["cell", "as built"])
@pytest.mark.parametrize("run", [1, 4])
def test_runs_deposit_the_same_fields(device, seed, order, run):
    """Every particle's mass and momentum reach the same nodes whether each particle adds its 27 deposits to
    the grid or a run's particles of one cell are summed first (m_i = Σ_p w_ip m_p, p_i = Σ_p w_ip (m_p (v_p +
    C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w_ip)), in cell order (many particles share a run's cell) and in the order
    they were built (almost none do): Σ m_i = Σ m_p, the same escape counter, every node equal to float32
    rounding, and with runs of one particle bitwise (on the CPU, where the sums keep their order)."""
    sim, _ = slab(seed, device, n=12000)  # ≈ 5 particles per cell
    if order == "cell":
        sim.sort_particles("cell")
        if run > 1:
            assert shared_cells(sim, run) > len(sim.particles) // 3, "sums merge"
    mp0, c0 = one_p2g(sim, 0)
    mp1, c1 = one_p2g(sim, run)
    torch.testing.assert_close(mp1[:, 3].sum(), sim.particles.mass.sum().double().cpu(), rtol=1e-6, atol=0.0)
    assert torch.equal(c0, c1), f"the same counters {c0.tolist()}"
    assert int(c0[COUNT_ESCAPED]) == 0
    if run == 1 and device == "cpu":
        assert torch.equal(mp0, mp1)
    else:
        scale = mp0.abs().amax(0)  # [4]: per component, the largest magnitude
        assert ((mp1 - mp0).abs() <= 1e-5 * scale).all()


def test_runs_with_fragments_advance_the_same(device, seed):
    """After a cut near one end the runs take the solo particles (most of them) and the fan-out the others
    (FractureFields' own fields, slot claims unchanged): three frames advance x, v and F as with one thread per
    particle to float32 rounding, and one P2G of the final state deposits every particle's mass. Where most
    particles take the slot path (a cut through the middle of this slab), P2G goes back to one per thread."""
    sims = []
    for run in (0, 4):
        sim, _ = slab(seed, device, sort="cell")
        # the runs leave the particles that are not solo to the fan-out
        sim.options = replace(sim.options, fanout=True, p2g_run=run)
        sim.latch(S.Topology.from_plane(sim.particles.x.cpu(), (0.18, 0.5, 0.5), (1.0, 0.2, 0.1), band_width=1.5 / 32))
        for _ in range(3):
            sim.advance(5e-3)
        sims.append(sim)
    plain, runs = sims
    solo = runs.slots.solo.bool()
    assert 0.5 < float(solo.float().mean()) < 0.95, "both the runs and the fan-out are exercised"
    assert runs.slots.run_length(1) == 4
    for name in ("x", "v", "F"):
        a, b = getattr(plain.particles, name).cpu(), getattr(runs.particles, name).cpu()
        assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"
    mp, _ = one_p2g(runs, 4)
    torch.testing.assert_close(mp[:, 3].sum(), runs.particles.mass.sum().double().cpu(), rtol=1e-6, atol=0.0)
    middle, topo = slab(seed, device, sort="cell")
    middle.options = replace(middle.options, fanout=True, p2g_run=4)
    middle.latch(topo)
    middle.advance(5e-3)
    slots = middle.slots
    assert float(slots.solo.float().mean()) < 0.5 and slots.run_length(1) == 0 and slots.run_length(0) == 4


def test_runs_are_on_only_for_cell_order_on_a_gpu(device):
    """Runs pay only where consecutive particles share cells: `sort_particles("cell")` turns them on (8
    particles per thread) on a GPU, the interleaved order turns them off, and the CPU keeps one particle per
    thread (a single thread runs the launch: nothing to save)."""
    sim, _ = slab(0, device)
    assert sim.options.p2g_run == 0
    sim.sort_particles("cell")
    assert sim.options.p2g_run == (8 if device != "cpu" else 0)
    sim.sort_particles("interleaved")
    assert sim.options.p2g_run == 0


def test_sorting_after_a_latch_orders_cells_by_fragment_and_keeps_the_topology(device, seed):
    """After a latch `sort_particles("cell")` orders each cell's particles by fragment (a run of P2G breaks at
    most once per fragment in a cell) and reorders the latched topologies with the particles."""
    from test_transfer_launch import slab

    sim, topo = slab(seed, device, 6, storage="boxes")
    sim.latch(topo)
    before = {k: getattr(sim.particles, k).clone() for k in ("x", "fragment", "band")}
    order = sim.sort_particles("cell")
    P, g = sim.particles, sim.grid
    for k, t in before.items():
        assert torch.equal(getattr(P, k), t[order]), k
    assert torch.equal(sim.topology.fragment.to(P.fragment.device, torch.int32), P.fragment)
    assert torch.equal(sim.topology.band.to(P.band.device).bool(), P.band.bool())
    cell = torch.floor((P.x - torch.tensor(g.origin, device=P.x.device)) / g.dx - 0.5).long()
    key = ((cell[:, 0] * g.shape[1] + cell[:, 1]) * g.shape[2] + cell[:, 2]) * 6 + P.fragment.long()
    assert bool((key[1:] >= key[:-1]).all()), "by cell, then fragment"
    assert bool((P.fragment[1:] != P.fragment[:-1]).any())
