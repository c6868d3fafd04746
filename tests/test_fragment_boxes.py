"""`sim.boxes.fragment_boxes.FragmentBoxes`: a dense box per fragment (docs/DESIGN.md "Grid storage: per-fragment boxes
(plan)") against the float64 twins on K dense fields. P2G puts each particle's deposits into its own
fragment's field only (mass and momentum of every field, relative error ≤ 1e-5); normalization and G2P read
each particle back from its own field; the contact where fields meet is `reference.contact_fields` with
mass-gradient normals, conserves each node's momentum, and only removes approach."""

import pytest
import torch
import warp as wp
from simutil import rel_err

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim import reference as ref
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.storage import COUNT_ESCAPED, N_COUNTS

N, n, DT, EPS_M = 3000, 24, 1e-3, 1e-9
GRAVITY = (0.0, 0.0, -9.8)


def clock(device, dt=DT):
    """The frame clock at the first substep of Δt (what the kernels read Δt and t from)."""
    c = FrameClock(device, 0)
    c.set(dt, [0.0])
    return c.view


def no_walls(device):
    return Boundaries([], device, (n, n, n), 0).colliders


def state(seed, device, sort=False):
    """Particles in the middle of a 24³ grid, four fragments by quadrant, random v, C, τ, F; `sort`: in the
    order of their stencil base nodes."""
    ensure_warp()
    g = torch.Generator().manual_seed(seed)
    x = 0.3 + 0.4 * torch.rand(N, 3, generator=g)
    if sort:
        base = torch.floor(x * n - 0.5).long()
        x = x[torch.argsort((base[:, 0] * n + base[:, 1]) * n + base[:, 2])]
    fragment = ((x[:, 0] > 0.5).int() + 2 * (x[:, 1] > 0.5).int()).to(torch.int32)
    tau = torch.randn(N, 3, 3, generator=g)
    P = {
        "x": x,
        "v": torch.randn(N, 3, generator=g),
        "C": torch.randn(N, 3, 3, generator=g),
        "F": torch.eye(3) + 0.1 * torch.randn(N, 3, 3, generator=g),
        "mass": 0.5 + torch.rand(N, generator=g),
        "volume": (0.5 + torch.rand(N, generator=g)) * 1e-4,
        "stress": tau + tau.transpose(1, 2),
        "fragment": fragment,
        "band": torch.zeros(N, dtype=torch.int32),
    }
    P = {k: t.to(device).contiguous() for k, t in P.items()}
    types = {"x": wp.vec3, "v": wp.vec3, "C": wp.mat33, "F": wp.mat33, "stress": wp.mat33}
    w = {k: wp.from_torch(t, dtype=types.get(k)) for k, t in P.items()}
    counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=device)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, device)
    boxes.fit(P["x"], P["fragment"])
    return P, w, counts, boxes


def reference_fields(P):
    cpu = {k: t.cpu().clone() for k, t in P.items()}  # copies: G2P updates the particles in place
    gm, gp, _ = ref.p2g(
        cpu["x"], cpu["v"], cpu["C"], cpu["mass"], cpu["volume"], cpu["stress"], cpu["fragment"], 4, (n, n, n),
        (0.0, 0.0, 0.0), 1.0 / n, DT,
    )  # fmt: skip
    return gm.reshape(4, n, n, n), gp.reshape(4, n, n, n, 3), cpu


def boxed(boxes, k, dense):  # the region of box k in a dense [n, n, n, ...] field
    lo, d = [int(v) for v in boxes.lo[k]], [int(v) for v in boxes.dims[k]]
    return dense[lo[0] : lo[0] + d[0], lo[1] : lo[1] + d[1], lo[2] : lo[2] + d[2]]


@pytest.mark.parametrize("sort", [False, True])
def test_each_box_is_its_fragments_stencils_plus_the_slack(device, seed, sort):
    """`fit` gives box k the nodes from the lowest to the highest stencil node of fragment k's particles,
    base = ⌊(x − origin)/Δx − ½⌋ in float64, widened by the slack and clamped into the grid; a fragment without
    particles gets a box of (slack + 1)³ nodes at the grid's first corner, which no particle reaches. The
    bounds are reduced a few particles at a time on the device, so the particles in any order (random, or
    sorted by cell as the solver keeps them) give the same boxes."""
    P, _, _, boxes = state(seed, device, sort=sort)
    fragment = P["fragment"].clone()
    fragment[fragment == 2] = 4  # fragment 2 has no particles; 4 is the largest id
    x = P["x"].clone()
    x[0] = torch.tensor([0.01, 0.5, 0.98])  # a particle near the grid's faces: its box is clamped there
    for slack in (1, 3):
        boxes.fit(x, fragment, slack=slack, K=6)
        base = torch.floor(x.double().cpu() / (1.0 / n) - 0.5).long()  # origin 0, Δx = 1/n
        for k in range(6):
            mine = fragment.cpu() == k
            lo, dims = boxes.lo[k].cpu().long(), boxes.dims[k].cpu().long()
            if not bool(mine.any()):
                assert lo.tolist() == [0, 0, 0] and dims.tolist() == [slack + 1] * 3, f"empty fragment {k}"
                continue
            want_lo = (base[mine].amin(0) - slack).clamp(0, n - 1)
            want_hi = (base[mine].amax(0) + 2 + slack).clamp(max=n - 1)
            assert lo.tolist() == want_lo.tolist(), (k, slack)
            assert (lo + dims - 1).tolist() == want_hi.tolist(), (k, slack)


@pytest.mark.parametrize("run", [0, 8])
def test_each_particle_deposits_into_its_own_fragments_box_only(device, seed, run):
    """One particle a thread, or runs of 8 consecutive particles summed in registers (sorted by cell, so runs
    share stencil bases; a change of fragment or base flushes): the same fields to float32 rounding, band
    particles' mass also in the band buffer."""
    P, w, counts, boxes = state(seed, device, sort=run > 0)
    P["band"].copy_(((P["x"][:, 0] - 0.5).abs() < 1.5 / n).to(torch.int32))
    boxes.p2g(w, clock(device), wp.from_torch(counts), run=run, band_flags=w["band"])
    assert int(counts[COUNT_ESCAPED]) == 0
    gm, gp, _ = reference_fields(P)
    cpu = {k: t.cpu() for k, t in P.items()}
    _, _, gb = ref.p2g(
        cpu["x"], cpu["v"], cpu["C"], cpu["mass"], cpu["volume"], cpu["stress"], cpu["fragment"], 4, (n, n, n),
        (0.0, 0.0, 0.0), 1.0 / n, DT, band=cpu["band"],
    )  # fmt: skip
    gb = gb.reshape(4, n, n, n)
    assert float(gb.sum()) > 0
    for k in range(4):
        a, b = int(boxes.offset[k]), int(boxes.offset[k + 1])
        band = boxes.band[a:b].reshape([int(d) for d in boxes.dims[k]]).cpu()
        assert rel_err(band, boxed(boxes, k, gb[k])) <= 1e-5, f"band mass of field {k} (seed {seed})"
    assert boxes.nodes < 4 * n**3 / 8, "the boxes hug their fragments"
    for k in range(4):
        m, p, _ = boxes.field(k)
        assert rel_err(m.cpu(), boxed(boxes, k, gm[k])) <= 1e-5, f"mass of field {k} (seed {seed})"
        assert rel_err(p.cpu(), boxed(boxes, k, gp[k])) <= 1e-5, f"momentum of field {k} (seed {seed})"
        assert float(boxed(boxes, k, gm[k]).sum()) == pytest.approx(float(gm[k].sum()), rel=1e-12), "all inside"


@pytest.mark.parametrize("run", [0, 8])
def test_a_stencil_outside_its_box_is_counted_and_not_deposited(device, seed, run):
    """Particles moved after the fit so that their stencils leave their fragment's box (one particle alone,
    and 24 consecutive ones, whose runs share stencil bases): each is counted once as an escape and deposits
    nothing; every other particle's mass lands in its own box."""
    P, w, counts, boxes = state(seed, device, sort=True)
    g = torch.Generator().manual_seed(seed + 1)
    lone = int(torch.randint(N, (1,), generator=g))
    shifted = torch.zeros(N, dtype=torch.bool)
    shifted[lone] = True
    shifted[N // 2 : N // 2 + 24] = True  # consecutive in cell order: runs of 8 that share bases
    P["x"][shifted.to(device), 2] = 0.95  # every box ends below z = 0.7 + its slack (and the grid at 1)
    x, k = P["x"].cpu().double(), P["fragment"].cpu().long()
    base = torch.floor(x * n - 0.5).long()
    lo, hi = boxes.lo.cpu().long()[k], boxes.lo.cpu().long()[k] + boxes.dims.cpu().long()[k] - 1
    outside = ((base < lo) | (base + 2 > hi)).any(1)
    assert torch.equal(outside, shifted)
    boxes.p2g(w, clock(device), wp.from_torch(counts), run=run)
    assert int(counts[COUNT_ESCAPED]) == int(outside.sum()), "each escaped particle counted once"
    kept = float(P["mass"].cpu().double()[~outside].sum())
    assert float(boxes.mp[: boxes.nodes, 3].double().sum()) == pytest.approx(kept, rel=1e-5)


def test_normalize_and_g2p_read_each_particle_back_from_its_own_field(device, seed):
    P, w, counts, boxes = state(seed, device)
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw)
    boxes.update(c, EPS_M, GRAVITY, fill_mass=float("inf"), centroids=wp.zeros(4, dtype=wp.vec3, device=device),
                 counts=cw, colliders=no_walls(device))  # fmt: skip
    gm, gp, cpu = reference_fields(P)
    gv = ref.grid_update(gm, gp, torch.zeros_like(gm), EPS_M, 0.0, DT, GRAVITY)  # no contact: the gate never opens
    for k in range(4):  # weighted by the node's mass: p/m of a node at a stencil's far edge is ill-conditioned
        m, _, vel = (t.cpu() for t in boxes.field(k))
        mv = boxed(boxes, k, gm[k])[..., None] * boxed(boxes, k, gv[k])
        assert rel_err(m[..., None] * vel, mv) <= 1e-5, f"velocity {k} (seed {seed})"
    boxes.g2p(w, c, wp.vec3(0.0, 0.0, 0.0), wp.vec3(1.0, 1.0, 1.0), cw)
    x1, v1, C1, F1 = ref.g2p(cpu["x"], cpu["F"], gv, cpu["fragment"], (0.0, 0.0, 0.0), 1.0 / n, DT)
    for name, theirs in (("x", x1), ("v", v1), ("C", C1), ("F", F1)):
        assert rel_err(P[name].cpu(), theirs) <= 1e-5, f"G2P {name} (seed {seed})"


def mass_gradients(gm):  # [K, n, n, n] -> [K, n, n, n, 3], central differences, zero beyond the grid
    pad = torch.nn.functional.pad(gm, (1, 1, 1, 1, 1, 1))
    return torch.stack(
        [
            (pad[:, 2:, 1:-1, 1:-1] - pad[:, :-2, 1:-1, 1:-1]),
            (pad[:, 1:-1, 2:, 1:-1] - pad[:, 1:-1, :-2, 1:-1]),
            (pad[:, 1:-1, 1:-1, 2:] - pad[:, 1:-1, 1:-1, :-2]),
        ],
        -1,
    ) * (0.5 * n)


def test_contact_where_fields_meet_is_the_reference_and_conserves_momentum(device, seed):
    P, w, counts, boxes = state(seed, device)
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw)
    gm, gp, cpu = reference_fields(P)
    fill = 0.05 * float(gm[gm > 0].mean())
    centroids = torch.stack([cpu["x"][cpu["fragment"] == k].mean(0) for k in range(4)])
    boxes.update(c, EPS_M, GRAVITY, fill, wp.from_torch(centroids.to(device).contiguous(), dtype=wp.vec3), cw,
                 no_walls(device), e=0.0, mu=0.3)  # fmt: skip
    gv = ref.grid_update(gm, gp, torch.zeros_like(gm), EPS_M, 0.0, DT, GRAVITY)
    G = mass_gradients(gm)
    # nodes with two or more fields: slots in fragment order (as the box kernel collects them)
    present = gm > EPS_M  # [4, n, n, n]
    nodes = torch.nonzero(present.sum(0) >= 2)  # [M, 3]
    assert len(nodes) > 20, "the quadrants meet along their faces"
    i, j, l = nodes.unbind(1)
    m, v, g = gm[:, i, j, l].T, gv[:, i, j, l].transpose(0, 1), G[:, i, j, l].transpose(0, 1)  # [M, 4], [M, 4, 3]
    frag = torch.where(m > EPS_M, torch.arange(4), torch.full_like(m, -1, dtype=torch.long))

    def normals(a, b, lo, hi):
        rows = torch.arange(len(nodes))
        d = g[rows, hi] - g[rows, lo]
        ok = d.norm(dim=1) > 1e-6 * (g[rows, lo].norm(dim=1) + g[rows, hi].norm(dim=1)) + 1e-30
        c = centroids.double()[hi] - centroids.double()[lo]
        return torch.where(
            ok[:, None], d / d.norm(dim=1, keepdim=True).clamp_min(1e-300), c / c.norm(dim=1, keepdim=True)
        )

    after = ref.contact_fields(v, m, frag, torch.zeros_like(m), EPS_M, 0.0, normals, e=0.0, mu=0.3,
                               touching=lambda a, b: m[:, a] + m[:, b] >= fill)  # fmt: skip
    assert float((after - v).norm(dim=2).max()) > 1e-3, "some fields approached and were projected"
    ours = torch.zeros_like(after)
    for k in range(4):
        vel = boxes.field(k)[2].cpu()
        lo = [int(t) for t in boxes.lo[k]]
        inside = present[k, i, j, l]
        ours[inside, k] = vel[i[inside] - lo[0], j[inside] - lo[1], l[inside] - lo[2]].double()
    mask = present[:, i, j, l].T
    assert rel_err((m[..., None] * ours)[mask], (m[..., None] * after)[mask]) <= 1e-5, f"contact (seed {seed})"
    momentum = lambda vel: (m[..., None] * vel * mask[..., None]).sum(1)  # noqa: E731
    scale = float((m[..., None] * v.abs()).sum(1).max())
    assert float((momentum(ours) - momentum(v)).abs().max()) <= 1e-5 * scale, "each node's momentum"


def deposited(P, w, counts, boxes, device):
    """P2G into the boxes: the counters' Warp view, the clock, the box masses (CPU, float64), a fill mass of 5 %
    of the mean occupied node's and the fragments' centroids (the mass-gradient normals' fallback)."""
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw)
    m = boxes.mp[: boxes.nodes, 3].double().cpu()
    fill = 0.05 * float(m[m > 0].mean())
    centroids = torch.stack([P["x"][P["fragment"] == k].mean(0) for k in range(boxes.K)]).contiguous()
    return cw, c, m, fill, wp.from_torch(centroids, dtype=wp.vec3)


@pytest.mark.parametrize("fragments", [2, 4])
def test_the_fast_math_grid_update_is_the_exact_one_to_float32_rounding(device, seed, fragments):
    """CUDA devices run the grid update compiled with fast math (approximate division and square root): at the
    quadrants' fields (two halves: pairs only; four quadrants: nodes of three and four fields too), contact and
    friction included, it gives the exact kernel's velocities to float32 rounding, so each node's momentum is
    conserved as before."""
    P, w, counts, boxes = state(seed, device)
    if fragments == 2:
        P["fragment"].remainder_(2)  # the halves x < 0.5 and x > 0.5
        boxes.fit(P["x"], P["fragment"])
    assert boxes.K == fragments
    cw, c, m, fill, centroids = deposited(P, w, counts, boxes, device)
    vel = {}
    for fast in (False, True):
        boxes.update(c, EPS_M, GRAVITY, fill, centroids, cw, no_walls(device), e=0.0, mu=0.3, fast_math=fast)
        vel[fast] = boxes.vel[: boxes.nodes].double().cpu()
    live = m > EPS_M
    p_exact, p_fast = m[live, None] * vel[False][live], m[live, None] * vel[True][live]
    assert float(p_exact.norm(dim=1).max()) > 0
    assert rel_err(p_fast, p_exact) <= 1e-5, f"seed {seed}"
    assert float((p_fast.sum(0) - p_exact.sum(0)).norm()) <= 1e-5 * float(p_exact.norm(dim=1).sum())


def test_per_pair_statistics_cover_the_first_ids_and_the_totals_every_pair(device, seed):
    """Per-pair contact rows exist for fragment ids below a cap (`physics.contact.PAIR_FRAGMENTS`, so a run allowed
    4,096 fragments keeps 128² rows, not 4,096²): the four quadrants' contact recorded with a cap of 2 keeps only the
    pair 0–1, equal to its row without the cap, while the totals count every gated pair either way."""
    from fracture_gs.sim.grid.fields import Grid
    from fracture_gs.sim.physics.contact import (
        N_PAIR_STATS,
        N_STATS,
        NEVER,
        PAIR_FIRST_T,
        PAIR_FRAGMENTS,
        PAIR_GATED,
        STAT_GATED,
    )

    big = Grid((0.0, 0.0, 0.0), 1.0 / n, (n, n, n), device, max_fragments=4096)
    assert big.pair_fragments == PAIR_FRAGMENTS and big.pair_stats.numel() == PAIR_FRAGMENTS**2 * N_PAIR_STATS
    P, w, counts, boxes = state(seed, device)
    cw, c, _, fill, centroids = deposited(P, w, counts, boxes, device)
    rows = {}
    for cap in (4, 2):
        stats = torch.zeros(N_STATS, device=device)
        pairs = torch.zeros(cap * cap * N_PAIR_STATS, device=device)
        pairs.view(-1, N_PAIR_STATS)[:, PAIR_FIRST_T] = NEVER
        boxes.update(c, EPS_M, GRAVITY, fill, centroids, cw, no_walls(device), e=0.0, mu=0.3,
                     stats=(wp.from_torch(stats), wp.from_torch(pairs), cap))  # fmt: skip
        rows[cap] = stats.cpu(), pairs.cpu().view(cap, cap, N_PAIR_STATS)
    (all4, pairs4), (all2, pairs2) = rows[4], rows[2]
    assert float(all4[STAT_GATED]) == float(all2[STAT_GATED]) > float(pairs4[0, 1, PAIR_GATED]) > 0
    assert float(pairs4[:, :, PAIR_GATED].sum()) == float(all4[STAT_GATED]), "every pair below the cap has a row"
    assert float(pairs2[0, 1, PAIR_GATED]) == float(pairs4[0, 1, PAIR_GATED])
    torch.testing.assert_close(pairs2[0, 1], pairs4[0, 1], rtol=1e-5, atol=1e-6 * float(pairs4[0, 1].abs().max()))


@pytest.mark.parametrize("fast", [False, True])
def test_recording_the_contact_statistics_changes_no_velocity(device, seed, fast):
    """The grid update is built with the contact statistics compiled in (when a run keeps them) or out (fewer
    registers, no atomics between the leaders' loads): at the quadrants' fields, nodes of two to four fields with
    friction, both builds give the same velocities (bitwise on the CPU; to float32 rounding with CUDA's
    compiler), and only the recording build writes statistics."""
    from fracture_gs.sim.physics.contact import N_PAIR_STATS, N_STATS, NEVER, PAIR_FIRST_T, STAT_GATED

    P, w, counts, boxes = state(seed, device)
    cw, c, m, fill, centroids = deposited(P, w, counts, boxes, device)
    stats = torch.zeros(N_STATS, device=device)
    pairs = torch.zeros(4 * 4 * N_PAIR_STATS, device=device)
    pairs.view(-1, N_PAIR_STATS)[:, PAIR_FIRST_T] = NEVER
    vel = {}
    for record in (False, True):
        kept = (wp.from_torch(stats), wp.from_torch(pairs), 4) if record else None
        boxes.update(c, EPS_M, GRAVITY, fill, centroids, cw, no_walls(device), e=0.0, mu=0.3, stats=kept,
                     fast_math=fast)  # fmt: skip
        vel[record] = boxes.vel[: boxes.nodes].clone()
        if not record:
            assert float(stats.abs().sum()) == 0.0, "the quiet build writes no statistics"
    assert float(stats[STAT_GATED]) > 0, "the recording build counts the gated pairs"
    live = (m > EPS_M).to(device)
    assert float(vel[True][live].norm(dim=1).max()) > 0
    if device == "cpu":
        assert torch.equal(vel[True], vel[False])
    else:
        torch.testing.assert_close(vel[False][live], vel[True][live], rtol=1e-6, atol=1e-7)


def test_one_box_is_the_shared_field_transfer_walls_included(device, seed):
    """With every particle in fragment 0 the boxes hold one field, and a substep through them (P2G, normalization,
    the domain walls, G2P) is the simulator's shared-field transfer: bitwise on the CPU, where both add the
    deposits in particle order, to float32 atomics' order on a GPU. A block falls into the floor, so the walls
    act."""
    from simutil import block, config, particles

    from fracture_gs import sim as S

    x, vol = block(
        (0.3, 0.3, 0.02), (0.6, 0.6, 0.2), 1.0 / 48, jitter=0.5, generator=torch.Generator().manual_seed(seed)
    )
    sims = []
    for _ in range(2):
        P = particles(x, vol, v=torch.tensor([0.3, 0.0, -2.0]).expand(len(x), 3).clone(), E=1e4, nu=0.3)
        sim = S.Simulator(config(24, variant="baseline", gravity=GRAVITY, dt=1e-3), P, device=device)
        sim.fit_active_box(0.01)
        sim.set_clock(1e-3)
        sim.compute_stress(sim.stress, commit=True)
        sims.append(sim)
    plain, boxed_sim = sims
    plain.transfer()
    boxes = FragmentBoxes(boxed_sim.grid.shape, boxed_sim.grid.origin, boxed_sim.grid.dx, device)
    P = boxed_sim.particles
    boxes.fit(P.x, torch.zeros_like(P.fragment))
    w = dict(boxed_sim.wp, fragment=wp.from_torch(torch.zeros_like(P.fragment)))
    cw = boxed_sim.wp["counts"]
    c = boxed_sim.clock.view
    boxes.p2g(w, c, cw)
    none = wp.zeros(1, dtype=wp.vec3, device=device)
    boxed_sim.boundaries.colliders.wall_cells = int(boxed_sim.cfg.wall_cells)
    boxes.update(c, boxed_sim.eps_m, GRAVITY, 0.0, none, cw, colliders=boxed_sim.boundaries.colliders)
    boxes.g2p(w, c, boxed_sim.lower, boxed_sim.upper, cw)
    floor = (plain.particles.v[:, 2] - (-2.0 - 9.8e-3)).abs() > 1e-3
    assert bool(floor.any()), "the floor changed some velocities"
    for name in ("x", "v", "C", "F"):
        a, b = getattr(plain.particles, name).cpu(), getattr(P, name).cpu()
        if device == "cpu":
            assert torch.equal(a, b), name
        else:
            assert rel_err(b, a) <= 1e-5, f"{name} (seed {seed})"


@pytest.mark.parametrize("fast", [False, True])
def test_latched_normal_contact_gated_by_both_band_masses(device, seed, fast):
    """The paper's contact for a plane cut: two fields, the latched normal n_Π, projected only where both
    fields' band masses exceed ε_b (band particles deposit their mass there too), as
    `reference.contact_fields` with its default band gate; approach-only, momentum conserving. Also the build
    CUDA devices run for it: fast math with the latched normals compiled in (`GRID_UPDATES_LATCHED`)."""
    P, w, counts, boxes = state(seed, device)
    x = P["x"]
    P["fragment"].copy_((x[:, 0] > 0.5).to(torch.int32))
    P["band"].copy_(((x[:, 0] - 0.5).abs() < 1.5 / n).to(torch.int32))
    P["v"][:, 0] = torch.where(x[:, 0] > 0.5, -1.0, 1.0)  # the halves approach along x
    boxes.fit(P["x"], P["fragment"])
    cw = wp.from_torch(counts)
    c = clock(device)
    boxes.p2g(w, c, cw, band_flags=w["band"])
    cpu = {k: t.cpu().clone() for k, t in P.items()}
    gm, gp, gb = ref.p2g(
        cpu["x"], cpu["v"], cpu["C"], cpu["mass"], cpu["volume"], cpu["stress"], cpu["fragment"], 2, (n, n, n),
        (0.0, 0.0, 0.0), 1.0 / n, DT, band=cpu["band"],
    )  # fmt: skip
    eps_b = 0.01 * float(gm[gm > 0].mean())
    while bool(((gb - eps_b).abs() < 1e-4 * eps_b).any()):  # no node's band mass at the gate itself: float32
        eps_b *= 1.01  # kernels and the float64 reference may round a node 1e-6 away from ε_b to either side
    none = wp.zeros(2, dtype=wp.vec3, device=device)
    boxes.update(c, EPS_M, GRAVITY, 0.0, none, cw, no_walls(device), e=0.0, mu=0.2, latched=(1.0, 0.0, 0.0),
                 eps_b=eps_b, fast_math=fast)  # fmt: skip
    gv = ref.grid_update(gm, gp, gb, EPS_M, eps_b, DT, GRAVITY)
    both = (gm > EPS_M).all(0)
    i, j, l = torch.nonzero(both).unbind(1)
    m, v, band = gm[:, i, j, l].T, gv[:, i, j, l].transpose(0, 1), gb[:, i, j, l].T  # [M, 2], [M, 2, 3], [M, 2]
    frag = torch.tensor([0, 1]).expand(len(i), 2)
    normal = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64).expand(len(i), 3)
    after = ref.contact_fields(v, m, frag, band, EPS_M, eps_b, lambda a, b, lo, hi: normal, e=0.0, mu=0.2)
    gated = (band > eps_b).all(1) & ((after - v).norm(dim=2) > 1e-6).any(1)
    assert int(gated.sum()) > 5, "band-supported nodes approached and were projected"
    assert bool(((band <= eps_b).any(1) & (m > EPS_M).all(1)).any()), "some meeting nodes are not band-supported"
    ours = torch.zeros_like(after)
    for k in range(2):
        vel = boxes.field(k)[2].cpu()
        lo = [int(t) for t in boxes.lo[k]]
        ours[:, k] = vel[i - lo[0], j - lo[1], l - lo[2]].double()
    assert rel_err(m[..., None] * ours, m[..., None] * after) <= 1e-5, f"contact (seed {seed})"


@pytest.mark.parametrize("fragments", [2, 6])
def test_a_substep_in_boxes_is_the_slot_storages(device, seed, fragments):
    """K fields in boxes against the slot storage on the same latched slab (K = 2: the latched normal and the
    band gate; K = 6 Voronoi pieces: mass-gradient normals and the fill gate; friction on, the pieces driven
    into each other): one substep moves every particle whose stencil meets at most two fields as the slot
    storage does, bitwise on the CPU where both add the deposits in particle order (at a node of three
    fields or more the Gauss–Seidel sweep goes in fragment order here, in slot order there: close, not
    equal), and records the same contact statistics (at K = 2: counts and first contact exact, the momentum
    sums to float32 rounding)."""
    from test_transfer_launch import slab

    from fracture_gs.sim.physics.contact import N_PAIR_STATS, N_STATS, NEVER, PAIR_FIRST_T, STAT_FIRST_T, STAT_GATED

    sims = []
    for _ in range(2):
        sim, topo = slab(seed, device, fragments, 8)
        sim.cfg.contact.friction = 0.3
        sim.latch(topo)
        P = sim.particles
        P.v.copy_(0.5 - P.x)  # every piece moves toward the slab's middle: the pieces press into each other
        sim.fit_active_box(0.01)
        sim.set_clock(1e-3)
        sim.compute_stress(sim.stress, commit=True)
        sims.append(sim)
    slots, boxed = sims
    slots.record_contact = True
    slots.transfer()
    P, K = boxed.particles, boxed.grid.pair_fragments
    stats = torch.zeros(N_STATS, device=device)
    stats[STAT_FIRST_T] = NEVER
    pair_stats = torch.zeros(K * K * N_PAIR_STATS, device=device)
    pair_stats.view(-1, N_PAIR_STATS)[:, PAIR_FIRST_T] = NEVER
    boxes = FragmentBoxes(boxed.grid.shape, boxed.grid.origin, boxed.grid.dx, device)
    boxes.fit(P.x, P.fragment)
    w, cw, c = boxed.wp, boxed.wp["counts"], boxed.cfg
    boxes.p2g(w, boxed.clock.view, cw, band_flags=w["band"])
    crowded = crowded_particles(boxes, P.x.cpu(), boxed.eps_m)  # [N] a stencil node holds three fields or more
    boxed.boundaries.colliders.wall_cells = int(c.wall_cells)
    n = tuple(float(a) for a in boxed.latched_normal)
    boxes.update(
        boxed.clock.view, boxed.eps_m, c.gravity, c.contact.fill * boxed.node_mass, w["centroids"], cw,
        boxed.boundaries.colliders, e=c.restitution, mu=0.3, latched=n, eps_b=boxed.eps_b,
        mass_gradient=boxed.normal_mode == 1, stats=(wp.from_torch(stats), wp.from_torch(pair_stats), K),
    )  # fmt: skip
    boxes.g2p(w, boxed.clock.view, boxed.lower, boxed.upper, cw)
    ref_stats = slots.grid.contact_stats.cpu()
    assert float(ref_stats[STAT_GATED]) > 10, "the pieces pressed into each other at many nodes"
    assert bool(crowded.any()) == (fragments > 2)
    for name in ("x", "v", "C", "F"):
        a, b = getattr(slots.particles, name).cpu(), getattr(P, name).cpu()
        if device == "cpu":
            assert torch.equal(a[~crowded], b[~crowded]), name
        else:
            assert rel_err(b[~crowded], a[~crowded]) <= 1e-5, f"{name} (seed {seed})"
        # where three or more fields meet, the boxes take the pairs in fragment order, the slots in slot order
        assert rel_err(b, a) <= 1e-2, f"{name} (seed {seed})"
    ours = stats.cpu()
    if fragments > 2:  # the sweep's order changes which later pairs still approach: the same contacts, near enough
        assert abs(float(ours[STAT_GATED] - ref_stats[STAT_GATED])) <= 0.05 * float(ref_stats[STAT_GATED])
        return
    assert torch.equal(ours[[0, 1, STAT_FIRST_T]], ref_stats[[0, 1, STAT_FIRST_T]]), (ours, ref_stats)
    scale = float(ref_stats[5])  # Σ|m v| before: the momentum sums' scale
    torch.testing.assert_close(ours[2:5], ref_stats[2:5], rtol=0.0, atol=1e-5 * scale)
    torch.testing.assert_close(ours[5:8], ref_stats[5:8], rtol=1e-5, atol=1e-6)
    gated = pair_stats.cpu().view(-1, N_PAIR_STATS)[:, -1]
    assert torch.equal(gated, slots.grid.pair_stats.cpu().view(-1, N_PAIR_STATS)[:, -1]), (
        "gated pairs per fragment pair"
    )


def crowded_particles(boxes, x, eps_m):  # [N, 3] -> [N] bool
    """Particles with a stencil node where three or more fields hold mass (after P2G)."""
    counts = torch.zeros(tuple(boxes.shape), dtype=torch.int64)
    for k in range(boxes.K):
        m = boxes.field(k)[0].cpu()
        lo, d = [int(v) for v in boxes.lo[k]], m.shape
        counts[lo[0] : lo[0] + d[0], lo[1] : lo[1] + d[1], lo[2] : lo[2] + d[2]] += (m > eps_m).long()
    nodes, _, _, _ = ref.stencil(x, boxes.origin, boxes.dx)  # [N, 27, 3]
    return (counts[nodes[..., 0], nodes[..., 1], nodes[..., 2]] >= 3).any(1)


def test_overlap_lists_grow_with_the_pieces_not_with_max_fragments(device, seed):
    """Boxes for up to 4,096 fragments allocate overlap lists for the pairs of boxes that overlap, not for
    4,096² pairs; 24 pieces outgrow the first lists, which grow (a new layout key: recorded launches record
    again), and every box's list names exactly the boxes that overlap it."""
    from fracture_gs.sim.providers.cuts import voronoi_labels
    from fracture_gs.sim.providers.voronoi import voronoi_sites

    P, w, counts, _ = state(seed, device)
    boxes = FragmentBoxes((n, n, n), (0.0, 0.0, 0.0), 1.0 / n, device, max_fragments=4096)
    assert boxes.over.numel() < 1024, "no max_fragments² tables"
    fragment, _ = voronoi_labels(P["x"].cpu(), voronoi_sites(P["x"].cpu(), 24, 0), 0.0)
    P["fragment"].copy_(fragment.to(device, torch.int32))
    key = boxes.layout_key
    boxes.fit(P["x"], P["fragment"])
    lo, hi = boxes.lo[: boxes.K].cpu(), (boxes.lo + boxes.dims - 1)[: boxes.K].cpu()
    meets = ((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None])).all(2) & ~torch.eye(boxes.K, dtype=torch.bool)
    assert int(meets.sum()) > 64 and boxes.layout_key != key
    start, over = boxes.over_start.cpu(), boxes.over.cpu()
    for k in range(boxes.K):
        assert over[start[k] : start[k + 1]].tolist() == torch.nonzero(meets[k]).flatten().tolist(), k
    cw = wp.from_torch(counts)
    boxes.p2g(w, clock(device), cw)
    assert int(counts[COUNT_ESCAPED]) == 0
    total = float(P["mass"].double().sum())
    assert abs(float(boxes.mp[: boxes.nodes, 3].double().sum()) - total) <= 1e-5 * total
