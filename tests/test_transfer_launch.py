"""How the transfer launches its threads on a GPU (DESIGN.md "Performance rules"): the particles that are
not solo first in G2P, and one P2G thread per (such particle, stencil node). Both change only which thread
does what; the physics is the same up to the order of float32 sums, which these tests bound."""

from dataclasses import replace

import pytest
import torch
from simutil import config, rel_err

from fracture_gs import sim as S
from fracture_gs.sim.providers.cuts import voronoi_labels
from fracture_gs.sim.providers.voronoi import voronoi_sites
from fracture_gs.sim.storage import COUNT_SLOT_OVERFLOW


def slab(seed, device, fragments=2, slots=8, n=3000, sort=None, storage="slots", variant="full"):
    """A slab at rest under gravity, long in x, cut in two across it (or into Voronoi pieces): particles
    far from the cuts are solo, the rest take the slot path. `sort`: `Simulator.sort_particles`' mode,
    applied before the cut is labelled; `storage`: sim.grid_storage."""
    g = torch.Generator().manual_seed(seed)
    x = torch.tensor([0.1, 0.35, 0.35]) + torch.tensor([0.8, 0.3, 0.3]) * torch.rand(n, 3, generator=g)
    P = S.Particles(x=x, mass=0.5 + torch.rand(n, generator=g), volume=torch.full((n,), 1e-5), E=1e4, nu=0.3)
    cfg = config(32, variant=variant, gravity=(0.0, 0.0, -9.8), dt=1e-3, field_slots=slots, grid_storage=storage)
    sim = S.Simulator(cfg, P, device=device)
    if sort is not None:
        sim.sort_particles(sort)
    x = sim.particles.x.cpu()
    if fragments == 2:
        topo = S.Topology.from_plane(x, (0.5, 0.5, 0.5), (1.0, 0.2, 0.1), band_width=1.5 / 32)
    else:
        fragment, band = voronoi_labels(x, voronoi_sites(x, fragments, seed), 1.5 / 32)
        topo = S.Topology(fragment=fragment, band=band, normal=(1.0, 0.0, 0.0), point=(0.5, 0.5, 0.5))
    return sim, topo


def advanced_pair(setting: str, frames: int, seed, device, *slab_args):
    """The same slab latched and advanced `frames` frames of 5 ms twice: with the launch switch `setting`
    (`SimOptions`) off, then on."""
    sims = []
    for on in (False, True):
        sim, topo = slab(seed, device, *slab_args)
        sim.options = replace(sim.options, **{setting: on})
        sim.latch(topo)
        for _ in range(frames):
            sim.advance(5e-3)
        sims.append(sim)
    return sims


def test_particles_that_are_not_solo_launch_first(device, seed):
    """G2P may launch the particles that are not solo first (`SimOptions.slow_first`, on by default on a
    GPU, where their slot lookups then run under the dense bulk): every particle is still gathered
    exactly once, so two pieces advance bitwise as with the plain launch (G2P is per particle), and the
    next P2G still deposits every particle's mass (Σ of every slot's mass = Σ m_p)."""
    plain, split = advanced_pair("slow_first", 3, seed, device)
    solo = split.slots.solo.bool()
    assert 0.05 < float(solo.float().mean()) < 0.95, "both launch parts are exercised"
    assert int(split.slots.first) == int((~solo).sum())
    assert torch.equal(split.slots.order[: int(split.slots.first)].sort().values.long(), torch.nonzero(~solo).flatten())
    split.compute_stress(split.stress, commit=False)
    split.p2g(1e-3)
    total = split.grid._mp[:, 3].sum().double()  # every slot, dense and pooled (solo deposits claim no owner)
    torch.testing.assert_close(total, split.particles.mass.sum().double(), rtol=1e-6, atol=0.0)
    for name in ("x", "v", "C", "F"):
        a, b = getattr(plain.particles, name).cpu(), getattr(split.particles, name).cpu()
        if device == "cpu":
            assert torch.equal(a, b), name
        elif name != "C":  # P2G's float32 atomics sum in another order on every run; C of a body at rest is that noise
            assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"


@pytest.mark.parametrize("fragments,slots", [(2, 8), (6, 2)])
def test_particles_that_are_not_solo_fan_out_one_thread_per_node(device, seed, fragments, slots):
    """The particles that are not solo may fan out (`SimOptions.fanout`, on by default on a GPU, so their
    slot lookups do not run 27 in a row after the dense bulk): in P2G one thread per stencil node makes the
    deposit the particle's own loop would, so one P2G puts every particle's mass and momentum into the same
    fields (on the CPU the claims come in the same order: the same slots and overflow counts, with 2 slots
    at Voronoi corners too), differing only by the order of float32 sums; in G2P the 32 lanes of a warp
    share a particle's stencil, or, when they are many, each reads the slots P2G's fan-out deposited into
    (kept in a cache) instead of looking them up: on the CPU (lane 0 gathers alone, in the loop's order)
    bitwise the same particles; three frames advance the same to float32 rounding."""
    sims = []
    for fanout in (False, True):
        sim, topo = slab(seed, device, fragments, slots)
        sim.options = replace(sim.options, fanout=fanout)
        sim.latch(topo)
        host = sim.slots
        assert host.fan_cap == 0 and host.slot_cache.numel() == 1, "nothing fans out before the frame's solo flags"
        for _ in range(3):
            sim.advance(5e-3)
        sims.append(sim)
    plain, fanned = sims
    solo = fanned.slots.solo.bool()
    assert float(solo.float().mean()) < 0.95, "the fan-out is exercised"
    assert fragments > 2 or float(solo.float().mean()) > 0.05, "so are the dense deposits (two pieces)"
    cap = fanned.slots.fan_cap  # a power of two, or every particle
    assert cap >= int((~solo).sum()) and (cap & (cap - 1) == 0 or cap == len(solo))
    assert fanned.slots.slot_cache.numel() == 27 * cap, "the slot cache is sized with the capacity"
    for name in ("x", "v", "F"):
        a, b = getattr(plain.particles, name).cpu(), getattr(fanned.particles, name).cpu()
        assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"
    # one P2G of the same state both ways
    grids = []
    for fanout in (False, True):
        fanned.options = replace(fanned.options, fanout=fanout)
        fanned.grid.reset_claims()
        fanned.counts.zero_()
        fanned.compute_stress(fanned.stress, commit=False)
        fanned.p2g(1e-3)
        g = fanned.grid
        grids.append((g._mp.cpu().double(), g._owner.cpu(), g.pool_owner.cpu(), fanned.counts.cpu()))
    (mp0, own0, pool0, c0), (mp1, own1, pool1, c1) = grids
    torch.testing.assert_close(mp1[:, 3].sum(), fanned.particles.mass.sum().double().cpu(), rtol=1e-6, atol=0.0)
    if device == "cpu":
        assert torch.equal(own0, own1) and torch.equal(pool0, pool1), "the same slots, claimed in the same order"
        assert torch.equal(c0, c1), f"the same counters {c0.tolist()} (escaped, clamped, slot and pool overflows)"
        if slots == 2:
            assert int(c0[COUNT_SLOT_OVERFLOW]) > 0, "the Voronoi corners overflow two slots"
        scale = mp0.abs().amax(0)  # [4]: per component, the largest magnitude
        assert ((mp1 - mp0).abs() <= 1e-5 * scale).all()
    # one G2P from the same fields both ways (the grid as the fanned-out P2G left it)
    fanned.set_clock(1e-3)
    fanned._update_grid()
    start = {name: getattr(fanned.particles, name).clone() for name in ("x", "v", "C", "F")}
    # slots looked up; a warp per listed particle, slots from P2G's cache, the solo ones in the same launch or
    # in their own; listed first, from the cache
    gathered = []
    arms = ((False, 0.0, False, False), (True, 1.0, False, True), (True, 1.0, False, False), (True, 0.0, True, False))
    for fanout, most, slow_first, one_gather in arms:
        for name, value in start.items():
            getattr(fanned.particles, name).copy_(value)
        switches = dict(fanout=fanout, g2p_fanout_max=most, slow_first=slow_first, one_gather=one_gather)
        fanned.options = replace(fanned.options, **switches)
        fanned.storage.g2p()
        gathered.append({name: getattr(fanned.particles, name).cpu().clone() for name in start})
    assert not torch.equal(gathered[1]["x"], start["x"].cpu()), "G2P moved the particles"
    for name, a, b in [(n, gathered[0][n], other[n]) for other in gathered[1:] for n in start]:
        if device == "cpu":
            assert torch.equal(a, b), name
        elif name != "C":  # the warp sums the 27 nodes as a tree, not in the loop's order
            assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"
        else:  # C = 4/Δx² Σ w v_i (x_i − x_p)ᵀ cancels for a body at rest: 27 roundings of |C| ≤ 6 max|v_i|/Δx
            bound = 27 * 2.0**-24 * 6 * float(gathered[0]["v"].norm(dim=1).max()) * 32
            assert float((b - a).abs().max()) <= bound, f"C (seed {seed})"


@pytest.mark.slow
@pytest.mark.parametrize("fragments", [2, 6])
def test_independent_launches_beside_each_other_change_nothing(device, seed, fragments):
    """On a GPU the pool's reset, the P2G fan-out and the pool pass run on a second stream beside the dense
    kernels (`SimOptions.concurrent`: a fork and a join per phase, parallel paths of the recorded substep).
    The dense grid pass leaves every node with a pool row to the pool pass, and the fan-out deposits other
    particles than the dense ones, so nothing either side writes is read by the other before the join:
    frames advance the same as with every launch in one stream, up to the order of P2G's float32 atomic
    sums (bitwise on the CPU, where the fork is a no-op)."""
    one, two = advanced_pair("concurrent", 4, seed, device, fragments, 8)
    assert int(two.grid.rows_used()) > 0, "the pool pass ran"
    if device.startswith("cuda"):
        assert two.slots.fan_cap > 0 and two.fork.forks > 0, "the fan-out ran on the fork's stream"
    for name in ("x", "v", "F"):
        a, b = getattr(one.particles, name).cpu(), getattr(two.particles, name).cpu()
        if device == "cpu":
            assert torch.equal(a, b), name
        else:
            assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"
