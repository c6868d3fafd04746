"""Each Warp kernel (stress, P2G, grid update, G2P) against its float64 torch reference on random
particles, plus partition of unity. Relative error ≤ 1e-5 (float32 kernels vs float64 truth)."""

import torch
import warp as wp
from simutil import config, rand_rotations, rel_err

from fracture_gs import sim as S
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim import reference as ref
from fracture_gs.sim.physics.constitutive import rotation_of

N = 3000


def random_state(seed, device, variant="baseline", n_grid=32):
    """Random particles inside a 32³ grid: random v, C, F = U diag(s) Vᵀ, mixed materials."""
    g = torch.Generator().manual_seed(seed)
    x = 0.25 + 0.5 * torch.rand(N, 3, generator=g)
    U, V = rand_rotations(N, g), rand_rotations(N, g)
    s = 0.6 + 0.8 * torch.rand(N, 3, generator=g, dtype=torch.float64)
    F = (U @ torch.diag_embed(s) @ V.transpose(1, 2)).float()
    P = S.Particles(
        x=x,
        v=torch.randn(N, 3, generator=g),
        C=torch.randn(N, 3, 3, generator=g) * 2.0,
        F=F,
        mass=0.5 + torch.rand(N, generator=g),
        volume=(0.5 + torch.rand(N, generator=g)) * 1e-3,
        E=1e3 + 1e4 * torch.rand(N, generator=g),
        nu=0.45 * torch.rand(N, generator=g),
        material=torch.randint(0, 4, (N,), generator=g, dtype=torch.int32),
        yield_stress=1e2 + 1e3 * torch.rand(N, generator=g),
    )
    cfg = config(n_grid, variant=variant, gravity=(0.3, -1.0, -9.8), dt=1e-3)
    return S.Simulator(cfg, P, device=device)


def test_stress_matches_reference(device, seed):
    sim = random_state(seed, device)
    P = sim.particles
    F0 = P.F.clone().cpu()
    sim.compute_stress(sim.stress, commit=True)
    tau, F_new, _ = ref.stress(F0, P.material.cpu(), P.E.cpu(), P.nu.cpu(), P.yield_stress.cpu(), P.alpha.cpu())
    for m in range(4):
        sel = P.material.cpu() == m
        assert rel_err(sim.stress.cpu()[sel], tau[sel]) <= 1e-5, f"model {m} stress (seed {seed})"
        assert rel_err(P.F.cpu()[sel], F_new[sel]) <= 1e-5, f"model {m} plastic F (seed {seed})"


def test_released_band_carries_no_stress_and_keeps_its_plastic_return(device, seed):
    """Eq. stress_release: a particle banded by an event ≤ `release` carries τ = 0 under every model, one banded
    by a later event keeps its stress, and the plastic models still commit their return mapping into F (the
    hyperelastic models skip τ's polar iterations there; the result is the same)."""
    from fracture_gs.sim.physics.constitutive import compute_stress

    sim = random_state(seed, device)
    P = sim.particles
    band = torch.randint(0, 3, (N,), generator=torch.Generator().manual_seed(seed), dtype=torch.int32)
    P.band.copy_(band.to(P.band.device))  # 0: not banded; 1, 2: banded by event 1 or 2
    F0, out = P.F.clone().cpu(), torch.full_like(sim.stress, float("nan"))
    w = sim.wp
    arrays = [w["F"], w["material"], w["E"], w["nu"], w["yield_stress"], w["hardening"], w["alpha"], w["band"]]
    wp.launch(compute_stress, dim=N, device=sim.device, inputs=arrays + [1, 1, wp.from_torch(out, dtype=wp.mat33)])
    released = band == 1
    tau, F_new, _ = ref.stress(
        F0, P.material.cpu(), P.E.cpu(), P.nu.cpu(), P.yield_stress.cpu(), P.alpha.cpu(), band=released, release=True
    )
    assert torch.equal(out.cpu()[released], torch.zeros(int(released.sum()), 3, 3)), f"seed {seed}"
    assert rel_err(out.cpu()[~released], tau[~released]) <= 1e-5, f"unreleased stress (seed {seed})"
    assert rel_err(P.F.cpu(), F_new) <= 1e-5, f"plastic F, released ones included (seed {seed})"


def test_p2g_grid_g2p_match_reference(device, seed):
    sim = random_state(seed, device)
    P, g, dt = sim.particles, sim.grid, 1e-3
    sim.compute_stress(sim.stress, commit=True)
    x0, F0, field = P.x.cpu().clone(), P.F.cpu().clone(), torch.zeros(N, dtype=torch.long)
    gm, gp, gb = ref.p2g(
        x0, P.v.cpu(), P.C.cpu(), P.mass.cpu(), P.volume.cpu(), sim.stress.cpu(), field, 1, g.shape, g.origin, g.dx, dt
    )
    sim.p2g(dt)
    assert rel_err(g.mass[:1].cpu(), gm) <= 1e-5, f"P2G mass (seed {seed})"
    assert rel_err(g.momentum[:1].cpu(), gp) <= 1e-5, f"P2G momentum (seed {seed})"
    sim.cfg.wall_cells = 0  # compare the pure update; boundaries are tested on their own
    sim.update_grid(dt)
    gv = ref.grid_update(gm, gp, gb, sim.eps_m, sim.eps_b, dt, sim.cfg.gravity)
    assert rel_err(g.velocity[:1].cpu(), gv) <= 1e-5, f"grid update (seed {seed})"
    sim.g2p(dt)
    x1, v1, C1, F1 = ref.g2p(x0, F0, g.velocity[:1].cpu().double(), field, g.origin, g.dx, dt)
    for name, ours, theirs in (("x", P.x, x1), ("v", P.v, v1), ("C", P.C, C1), ("F", P.F, F1)):
        assert rel_err(ours.cpu(), theirs) <= 1e-5, f"G2P {name} (seed {seed})"


def test_partition_of_unity_mass(device, seed):
    """Σ_i m_i = Σ_p m_p: the B-spline weights of every particle sum to one."""
    sim = random_state(seed, device)
    sim.p2g(1e-3)
    total = sim.grid.mass.double().sum()
    assert abs(float(total / sim.particles.mass.double().sum()) - 1) <= 1e-6, f"seed {seed}"


@wp.kernel
def _rotation_of_kernel(F: wp.array(dtype=wp.mat33), R: wp.array(dtype=wp.mat33)):
    p = wp.tid()
    R[p] = rotation_of(F[p])


def test_fixed_corotated_rotation_is_the_polar_factor(device, seed):
    """R of fixed-corotated (`constitutive.rotation_of`: scaled Newton where det F > 0, the SVD where F
    is inverted or nearly flat) is a rotation (RᵀR = I, det R = +1) equal to U Vᵀ of the float64 SVD
    with rotations U, V on either side of the Newton/SVD switch, to 64 float32 roundings times the polar
    factor's condition number σ₁/(|σ₂| − |σ₃|) (≤ 1e-5 where that is ≤ 10; 40 seeds stayed under 17
    roundings), and finite for every F."""
    g = torch.Generator().manual_seed(seed)
    n = 4096
    U, V = rand_rotations(n, g), rand_rotations(n, g)
    s = torch.exp(torch.empty(n, 3, dtype=torch.float64).uniform_(-2.5, 2.5, generator=g))  # cond up to ~150
    s = s.sort(dim=1, descending=True).values
    k = n // 8
    s[:k, 2] *= -1  # inverted (the smallest singular value carries det F's sign)
    # det F just above and below the Newton/SVD switch
    s[k : 2 * k, 2] = s[k : 2 * k, 0] * 1e-4 * torch.rand(k, generator=g, dtype=torch.float64)
    s[2 * k : 3 * k] *= 1e4  # huge
    s[3 * k : 4 * k] *= 1e-4  # tiny
    F = U @ torch.diag_embed(s) @ V.transpose(1, 2)
    F[4 * k : 4 * k + 8] = 0.0  # degenerate
    F[4 * k + 8 : 4 * k + 16] = torch.eye(3, dtype=torch.float64)
    ensure_warp()
    Fd, Rd = F.float().to(device), torch.zeros(n, 3, 3, device=device)
    wp.launch(
        _rotation_of_kernel,
        dim=n,
        device=device,
        inputs=[wp.from_torch(Fd, dtype=wp.mat33), wp.from_torch(Rd, dtype=wp.mat33)],
    )
    R = Rd.cpu().double()
    assert torch.isfinite(R).all()
    eye = torch.eye(3, dtype=torch.float64).expand(n, 3, 3)
    assert (R.transpose(1, 2) @ R - eye).abs().max() <= 1e-5
    assert (torch.linalg.det(R) - 1).abs().max() <= 1e-5
    # U Vᵀ is well defined where no two singular values nearly cancel (σ_i + σ_j ≫ 0)
    a = s.abs().sort(dim=1, descending=True).values
    gap = (a[:, 1] - a[:, 2]) / a[:, 0]  # 1 / condition number of U Vᵀ
    well = gap > 1e-2
    well[4 * k : 4 * k + 8] = False
    expected = U @ V.transpose(1, 2)
    expected[4 * k + 8 : 4 * k + 16] = torch.eye(3, dtype=torch.float64)
    err = (R - expected).abs().amax(dim=(1, 2))
    bound = 64 * 2.0**-24 / gap.clamp_min(1e-2)
    worst = (err / bound)[well].max()
    assert worst <= 1, f"|R − U Vᵀ| is {worst:.2f} of its bound (seed {seed})"
    assert err[well & (gap >= 0.1)].max() <= 1e-5
