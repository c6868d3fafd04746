"""Energy (`fracture_gs.sim.energy`): each model's ψ is the energy of the stress the solver simulates, the
closed forms hold, a dropped elastic block never gains energy and loses some at the floor, and a fracture
event in a real run adds none."""

import math

import pytest
import torch
from simutil import block, config, particles, rand_rotations

from fracture_gs import sim as S
from fracture_gs.sim import reference as ref
from fracture_gs.sim.diagnostics import energy as E
from fracture_gs.sim.physics.constitutive import MATERIAL_IDS, dp_alpha


def deformations(n, lo, hi, generator):
    """F = U diag(s) Vᵀ with random rotations U, V and stretches s uniform in [lo, hi] ([n, 3, 3], float64)."""
    U, V = rand_rotations(n, generator), rand_rotations(n, generator)
    s = lo + (hi - lo) * torch.rand(n, 3, generator=generator, dtype=torch.float64)
    return U @ torch.diag_embed(s) @ V.transpose(1, 2)


CASES = {
    # model: (stretch range, yield stress, friction angle): states the model keeps elastic
    "fixed_corotated": ((0.7, 1.3), 1e4, 30.0),
    "neo_hookean": ((0.7, 1.3), 1e4, 30.0),
    "stvk_hencky_vm": ((0.8, 1.2), 1e30, 30.0),  # never yields: the elastic energy of F itself
    "drucker_prager": ((0.85, 0.97), 1e4, 45.0),  # compressed inside the cone (no return)
}


@pytest.mark.parametrize("model", list(CASES))
def test_energy_density_derivative_is_the_simulated_stress(model, seed):
    """For every model, the central finite difference of ψ against each entry of F equals the first
    Piola–Kirchhoff stress P = τ F⁻ᵀ of the float64 reference of the kernels (`reference.stress`) to
    1e-6 relative: ψ is the potential of the stress the solver applies (a wrong factor, sign or term
    in ψ fails it)."""
    g = torch.Generator().manual_seed(seed)
    (lo, hi), ys, phi = CASES[model]
    n = 16
    F = deformations(n, lo, hi, g)
    mat = torch.full((n,), MATERIAL_IDS[model], dtype=torch.int32)
    Ey = 1e4 + 9e4 * torch.rand(n, generator=g, dtype=torch.float64)
    nu = 0.05 + 0.4 * torch.rand(n, generator=g, dtype=torch.float64)
    yield_stress = torch.full((n,), ys, dtype=torch.float64)
    alpha = dp_alpha(torch.full((n,), phi, dtype=torch.float64))
    tau, F_new, _ = ref.stress(F, mat, Ey, nu, yield_stress, alpha)
    assert torch.allclose(F_new, F, atol=1e-12), "the test states are elastic (no plastic return)"
    P = tau @ torch.linalg.inv(F).transpose(1, 2)
    h = 1e-6
    fd = torch.zeros_like(F)
    for i in range(3):
        for j in range(3):
            d = torch.zeros(3, 3, dtype=torch.float64)
            d[i, j] = h
            up = E.density(F + d, mat, Ey, nu, yield_stress, alpha)
            down = E.density(F - d, mat, Ey, nu, yield_stress, alpha)
            fd[:, i, j] = (up - down) / (2 * h)
    err = ((fd - P).flatten(1).norm(dim=1) / P.flatten(1).norm(dim=1)).max()
    assert err <= 1e-6, f"{model}: ‖∂ψ/∂F − P‖/‖P‖ = {err:.3g} (seed {seed})"


@pytest.mark.parametrize("model", ["stvk_hencky_vm", "drucker_prager"])
def test_plastic_models_count_the_energy_of_the_returned_deformation(model, seed):
    """Past the yield surface (von Mises) or outside the cone (Drucker–Prager, in shear and in tension) the
    stored energy is that of the elastic F the kernels' return maps to (`reference.stress`'s F_new), lower
    than the energy of the trial F: plastic flow dissipates, it stores nothing."""
    g = torch.Generator().manual_seed(seed)
    n = 32
    F = deformations(n, 0.7, 1.4, g)
    mat = torch.full((n,), MATERIAL_IDS[model], dtype=torch.int32)
    Ey, nu = torch.full((n,), 5e4, dtype=torch.float64), torch.full((n,), 0.3, dtype=torch.float64)
    yield_stress = torch.full((n,), 500.0, dtype=torch.float64)
    alpha = dp_alpha(torch.full((n,), 20.0, dtype=torch.float64))
    _, F_new, _ = ref.stress(F, mat, Ey, nu, yield_stress, alpha)
    plastic = (F_new - F).flatten(1).norm(dim=1) > 1e-6
    assert plastic.sum() >= n // 2, "most states flow plastically"
    psi = E.density(F, mat, Ey, nu, yield_stress, alpha)
    mu, lam = Ey / (2 * (1 + nu)), Ey * nu / ((1 + nu) * (1 - 2 * nu))  # Lamé, by hand
    eps = torch.log(torch.linalg.svdvals(F_new).clamp_min(1e-4))
    hencky = mu * (eps**2).sum(1) + 0.5 * lam * eps.sum(1) ** 2  # of the returned F, by hand
    assert torch.allclose(psi, hencky, rtol=1e-9, atol=1e-9), (psi - hencky).abs().max()
    trial = E.density(F, torch.full((n,), MATERIAL_IDS["stvk_hencky_vm"], dtype=torch.int32), Ey, nu, 1e30 * Ey)
    assert (psi[plastic] < trial[plastic] - 1e-6).all(), "the return lowers the stored energy"


def test_closed_forms():
    """ψ(R) = 0 for a rotation in every model; fixed-corotated uniaxial stretch s = 1.2 with E = 1e5,
    ν = 0.25 (μ = λ = 4e4 Pa): μ(s−1)² + λ/2 (s−1)² = 1600 + 800 = 2400 J/m³, neo-Hookean the same
    stretch: μ/2 (s² − 1) − μ ln s + λ/2 ln² s = 8800 − 7292.62 + 664.83 = 2171.96 J/m³; a block
    lifted by h = 0.25 m gains m g h; particles of 2 kg at 3 m/s have ½ m v² = 9 J each."""
    R = rand_rotations(8, torch.Generator().manual_seed(0))
    one = torch.ones(8, dtype=torch.float64)
    for name, model in MATERIAL_IDS.items():
        mat = torch.full((8,), model, dtype=torch.int32)
        psi = E.density(R, mat, 1e5 * one, 0.25 * one, 1e4 * one, dp_alpha(30.0) * one)
        assert psi.abs().max() < 1e-6, (name, psi)
    F = torch.diag(torch.tensor([1.2, 1.0, 1.0], dtype=torch.float64))[None]
    ones = torch.ones(1, dtype=torch.float64)
    fc = E.density(F, torch.zeros(1, dtype=torch.int32), 1e5 * ones, 0.25 * ones)
    assert math.isclose(float(fc), 2400.0, rel_tol=1e-12)
    nh = E.density(F, torch.ones(1, dtype=torch.int32), 1e5 * ones, 0.25 * ones)
    assert float(nh) == pytest.approx(2171.9607, abs=1e-4)

    x, vol = block((0.4, 0.4, 0.3), (0.5, 0.5, 0.4), 1 / 40)
    P = particles(x, vol, rho=800.0)
    lifted = particles(x + torch.tensor([0.0, 0.0, 0.25]), vol, rho=800.0)
    g, ref_point = (0.0, 0.0, -9.81), (0.0, 0.0, 0.0)
    mass = float(P.mass.double().sum())
    dE = E.energies(lifted, g, ref_point)[1] - E.energies(P, g, ref_point)[1]
    assert math.isclose(float(dE), mass * 9.81 * 0.25, rel_tol=1e-6)
    v = torch.tensor([[3.0, 0.0, 0.0], [0.0, 0.0, -3.0]])
    moving = S.Particles(x=torch.rand(2, 3), v=v, mass=torch.full((2,), 2.0))
    assert float(E.energies(moving, (0.0, 0.0, 0.0), ref_point)[0]) == pytest.approx(18.0, rel=1e-12)


def test_reference_point_is_the_lowest_grid_corner():
    """The zero of the gravitational energy is the grid corner lowest along g: the floor corner for
    g = −z, the +x corner for g = +x, so every particle in the grid has E_g ≥ 0."""
    assert E.reference_point((0.1, 0.2, 0.3), 0.5, (5, 6, 7), (0.0, 0.0, -9.8))[2] == pytest.approx(0.3)
    assert E.reference_point((0.1, 0.2, 0.3), 0.5, (5, 6, 7), (9.8, 0.0, 0.0))[0] == pytest.approx(2.1)


def test_drivers_are_the_moving_boundaries_while_they_act():
    """A moving cuboid or a flying ball drives while its window overlaps the frame, a velocity region in the
    substep it acts, an impulse over its duration; a static plane and a still cuboid never drive."""
    grip = S.CuboidBoundary(lower=(0, 0, 0), upper=(1, 1, 1), velocity=(0.1, 0, 0), end=0.3)
    still = S.CuboidBoundary(lower=(0, 0, 0), upper=(1, 1, 1), velocity=(0.0, 0, 0))
    kick = S.ParticleRegion(kind="velocity", upper=(1, 1, 1), velocity=(0.2, 0, 0), start=0.0, end=0.0)
    floor = S.PlaneBoundary()
    assert E.drivers_active([grip], 0.29, 0.30) and not E.drivers_active([grip], 0.31, 0.32)
    assert not E.drivers_active([still, floor], 0.0, 1.0)
    assert E.drivers_active([kick], 0.0, 0.005, 1e-4) and not E.drivers_active([kick], 0.005, 0.01, 1e-4)
    ball = S.SphereBoundary(center=(0, 0, 0), radius=0.1, velocity=(3.0, 0, 0), end=0.1)
    assert E.drivers_active([ball], 0.05, 0.06) and not E.drivers_active([ball], 0.11, 0.12)


def drop(device, frames=24):
    """An elastic block (E = 2e5 Pa) released at rest 0.1 m above a slip floor at z = 0.3; 3,375 particles."""
    x, vol = block((0.4, 0.4, 0.4), (0.55, 0.55, 0.55), 1 / 100)
    P = particles(x, vol, rho=500.0, E=2e5, nu=0.3)
    floor = S.PlaneBoundary(point=(0.0, 0.0, 0.3), normal=(0.0, 0.0, 1.0), mode="slip")
    sim = S.Simulator(config(32, gravity=(0.0, 0.0, -9.8), dt=5e-4, boundaries=[floor]), P, device=device)
    tracker = sim.diagnostics_tracker()
    rows, lowest = [tracker.snapshot()], []
    for _ in range(frames):
        sim.advance(0.01)
        rows.append(tracker.history[-1])
        lowest.append(float(sim.particles.x[:, 2].min()))
    return rows, lowest


@pytest.mark.slow
def test_drop_never_gains_energy_and_the_floor_takes_some(device):
    """A block dropped onto a slip floor: (1) in free fall kinetic energy gained equals potential energy
    lost within 2 % (symplectic Euler loses O(Δt)); (2) from frame to frame the total never rises by more
    than 1 % of the frame's total; (3) the impact removes energy: the total after the block has landed is
    below its value at the impact frame by over 20 % of the kinetic energy it arrived with. The elastic
    term matters: at the deepest compression it holds a fifth of the energy, and a total without it
    would rise by over 10 % as the block springs back."""
    rows, lowest = drop(device)
    dx = 1 / 32
    impact = next(f for f, z in enumerate(lowest, start=1) if z < 0.3 + dx)  # first frame near the floor
    assert 5 < impact < 30, impact
    before = rows[impact - 2]
    gained = before["energy_kinetic"] - rows[0]["energy_kinetic"]
    lost = rows[0]["energy_gravity"] - before["energy_gravity"]
    assert lost > 0 and abs(gained / lost - 1) < 0.02, (gained, lost)
    for a, b in zip(rows, rows[1:]):
        assert b["energy_total"] - a["energy_total"] <= 0.01 * b["energy_total"], (a["frame"], b["energy_total"])
        assert b["energy_total"] == pytest.approx(b["energy_kinetic"] + b["energy_gravity"] + b["energy_elastic"])
    arrived = rows[impact - 1]["energy_kinetic"]
    assert rows[impact + 8]["energy_total"] < rows[impact - 1]["energy_total"] - 0.2 * arrived
    assert not any(r["energy_driven"] for r in rows), "a static floor is not a driver"


@pytest.mark.slow
def test_fracture_events_add_no_energy_in_a_real_run(device):
    """plate_drop at 3,000 particles with FractureFields: the stress provider latches again and again at
    the impact. Across every latch frame and the frame after it (the first simulated with the new
    fragment fields) the total energy rises by at most 1 % of the frame's total, and no frame of this
    closed system (gravity, a static floor) is a violation: an event never adds energy."""
    from fracture_gs.io.config import load_config
    from fracture_gs.pipeline import load_scene, make_simulator
    from fracture_gs.render_sim.energy_report import energy_summary

    cfg = load_config("plate_drop")
    cfg.particles = 3000
    sim = make_simulator(cfg, load_scene(cfg, device), "full", device)
    tracker = sim.diagnostics_tracker()
    rows = [tracker.snapshot()]
    while len(sim.topologies) < 2 or rows[-1]["latches"] > rows[-2]["latches"]:
        assert sim.frame < 30, "plate_drop latches twice by frame 30"
        sim.advance(cfg.frame_dt)
        rows.append(tracker.history[-1])
    e = energy_summary(rows)
    assert len(e["events"]) >= 2 and e["closed"], e
    for ev in e["events"]:
        assert ev["fraction"] <= 0.01 and ev["next_fraction"] <= 0.01, ev
    assert not e["violations"], e["violations"]
    assert e["final_total"] < e["initial_total"], "the impact and the fracture dissipate"


def rows_of(totals, driven=(), latches=None):
    """Metrics rows with the given totals (frames 0, 1, …), driven frames and latch counts."""
    latches = latches or [0] * len(totals)
    return [
        {"frame": f, "energy_total": t, "energy_driven": f in driven, "latches": k}
        for f, (t, k) in enumerate(zip(totals, latches))
    ]


def test_summary_flags_rises_only_without_drivers():
    """A 2 % rise in a frame without drivers is a violation (summary, summary.md line, CLI warning); the
    same rise while a driver acts, or a 0.5 % rise, is not; an event's ΔE is that of its latch frame and
    the next, as fractions of the frame's total."""
    from fracture_gs.render_sim.energy_report import energy_line, energy_summary, energy_warning

    e = energy_summary(rows_of([10.0, 9.0, 9.18, 9.0, 9.045], latches=[0, 0, 0, 1, 1]))
    assert [v["frame"] for v in e["violations"]] == [2] and e["closed"]
    assert e["max_increase"]["frame"] == 2 and e["max_increase"]["fraction"] == pytest.approx(0.18 / 9.18)
    (ev,) = e["events"]
    assert ev["frame"] == 3 and ev["fraction"] == pytest.approx(-0.18 / 9.18)
    assert ev["next_fraction"] == pytest.approx(0.045 / 9.045)
    line = energy_line("full", e)
    assert "event 1 at frame 3: ΔE = -1.96 % (next frame +0.50 %)" in line and "VIOLATION" in line
    warning = energy_warning([{"variant": "full", "energy": e}])
    assert warning and "full in 1 frame(s), worst +1.96 % at frame 2" in warning
    driven = energy_summary(rows_of([10.0, 9.0, 9.18], driven={2}))
    assert not driven["violations"] and not driven["closed"] and "not a closed system" in energy_line("b", driven)
    assert energy_warning([{"variant": "b", "energy": driven}]) is None
    assert not energy_summary(rows_of([10.0, 9.0, 9.045]))["violations"]
