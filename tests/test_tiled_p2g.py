"""P2G through a block-shared node tile (`tile_kernels.p2g_tiled`, DESIGN.md "Performance rules"): a block
of particles adds its deposits into a shared TILE³ tile of nodes and then adds each tile node to the grid
once; deposits outside the tile go to the grid directly. Only who adds what changes, so the fields are the
same up to the order of float32 sums (bitwise with one lane per block, as the CPU runs it by default)."""

import pytest
import torch
import warp as wp
from simutil import rel_err
from test_transfer_launch import slab

from fracture_gs.sim.layout import COUNT_ESCAPED
from fracture_gs.sim.tile_kernels import TILE


def one_p2g(sim, tiled: bool):
    """The grid after one P2G of the current state ([nodes + pool, 4] float64) and the counters."""
    sim.tiled_p2g = tiled
    sim.grid.reset_claims()
    sim.counts.zero_()
    sim.compute_stress(sim.stress, commit=False)
    sim.p2g(1e-3)
    return sim.grid._mp.cpu().double(), sim.counts.cpu().clone()


def spread_blocks(sim, bd: int) -> int:
    """Blocks of `bd` consecutive particles whose stencils do not fit one tile (their deposits partly bypass it)."""
    g = sim.grid
    base = torch.floor((sim.particles.x.cpu() - torch.tensor(g.origin)) / g.dx - 0.5).long()  # [N, 3]
    n = len(base) // bd * bd
    b = base[:n].view(-1, bd, 3)
    return int(((b.amax(1) - b.amin(1) + 3) > TILE).any(1).sum())


@pytest.mark.parametrize("lanes", [1, 32])
@pytest.mark.parametrize("order", ["morton", "as built"])
def test_tiled_p2g_deposits_the_same_fields(device, seed, monkeypatch, lanes, order):
    """Every particle's mass and momentum reach the same nodes whether P2G adds them to the grid one by one
    or through a block's shared tile (m_i = Σ_p w_ip m_p, p_i = Σ_p w_ip (m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p
    ∇w_ip)), for particles sorted along a Morton curve (most deposits in the tile) and in the order they were
    built (many blocks spread wider than the tile: those deposits take the direct path): Σ m_i = Σ m_p, the
    same escape counter, and every node equal to float32 rounding; with one lane per block, bitwise."""
    if lanes > 1 and device == "cpu":
        monkeypatch.setattr(wp.config, "enable_cpu_blocks", True)  # the CPU then runs 32 lanes per block
    sim, _ = slab(seed, device)
    sim.tile_block = 128 if device != "cpu" else lanes
    if order == "morton":
        sim.sort_particles("morton")
    bd = 1 if device == "cpu" and lanes == 1 else sim.tile_block
    if order != "morton" and bd > 1:
        assert spread_blocks(sim, bd) > 0, "the direct path is exercised"
    mp0, c0 = one_p2g(sim, False)
    mp1, c1 = one_p2g(sim, True)
    torch.testing.assert_close(mp1[:, 3].sum(), sim.particles.mass.sum().double().cpu(), rtol=1e-6, atol=0.0)
    assert torch.equal(c0, c1), f"the same counters {c0.tolist()}"
    assert int(c0[COUNT_ESCAPED]) == 0
    if bd == 1:
        assert torch.equal(mp0, mp1)
    else:
        scale = mp0.abs().amax(0)  # [4]: per component, the largest magnitude
        assert ((mp1 - mp0).abs() <= 1e-5 * scale).all()


def test_tiled_p2g_with_fragments_advances_the_same(device, seed):
    """After a cut the tile takes the solo particles and the fan-out the others
    (FractureFields' own fields, slot claims unchanged): three frames advance x, v and F as with the plain
    P2G to float32 rounding (on the CPU with one lane per block, bitwise), and one P2G of the final state
    deposits every particle's mass."""
    sims = []
    for tiled in (False, True):
        sim, topo = slab(seed, device, sort="morton")
        sim.fanout = True  # the tiled P2G leaves the particles that are not solo to the fan-out
        sim.tiled_p2g = tiled
        sim.latch(topo)
        for _ in range(3):
            sim.advance(5e-3)
        sims.append(sim)
    plain, tiled = sims
    solo = tiled.solo.bool()
    assert 0.05 < float(solo.float().mean()) < 0.95, "both the tile and the fan-out are exercised"
    for name in ("x", "v", "F"):
        a, b = getattr(plain.particles, name).cpu(), getattr(tiled.particles, name).cpu()
        if device == "cpu":
            assert torch.equal(a, b), name
        else:
            assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"
    mp, _ = one_p2g(tiled, True)
    torch.testing.assert_close(mp[:, 3].sum(), tiled.particles.mass.sum().double().cpu(), rtol=1e-6, atol=0.0)


def test_tiled_p2g_is_on_only_for_morton_order_on_a_gpu(device):
    """The tile pays only when a block's particles share a few cells: `sort_particles("morton")` turns it on
    on a GPU, any other order turns it off, and the CPU (one lane per block) keeps the plain P2G."""
    sim, _ = slab(0, device)
    assert not sim.tiled_p2g
    sim.sort_particles("morton")
    assert sim.tiled_p2g == (device != "cpu")
    sim.sort_particles("interleaved")
    assert not sim.tiled_p2g
