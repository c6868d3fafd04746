"""A captured object's resolution, particle sample, carried Gaussians, material presets, region of interest
and crack faces (fracture_gs/capture/{resolution,sample,materials,fit}.py, render/crack_faces.py)."""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.fit import auto_roi
from fracture_gs.capture.materials import PRESETS, apply_material
from fracture_gs.capture.resolution import BUDGETS, choose, probe
from fracture_gs.capture.sample import sample
from fracture_gs.config import CaptureConfig, SceneConfig
from fracture_gs.io.gaussian_set import GaussianSet
from fracture_gs.render.crack_faces import S_MIN, CrackFaces


def box_surface(lo, hi, spacing: float, seed: int = 0) -> GaussianSet:
    """Gaussians on the six faces of the box [lo, hi] [m], `spacing` apart, flat along each face's normal."""
    gen = torch.Generator().manual_seed(seed)
    lo, hi = torch.tensor(lo, dtype=torch.float64), torch.tensor(hi, dtype=torch.float64)
    pts, scales = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        nu = max(2, int(math.ceil(float(hi[u] - lo[u]) / spacing)) + 1)
        nv = max(2, int(math.ceil(float(hi[v] - lo[v]) / spacing)) + 1)
        gu, gv = torch.meshgrid(
            torch.linspace(0, 1, nu, dtype=torch.float64), torch.linspace(0, 1, nv, dtype=torch.float64), indexing="ij"
        )
        for side in (lo[axis], hi[axis]):
            p = torch.zeros(nu * nv, 3, dtype=torch.float64)
            p[:, u] = lo[u] + gu.flatten() * (hi[u] - lo[u])
            p[:, v] = lo[v] + gv.flatten() * (hi[v] - lo[v])
            p[:, axis] = side
            s = torch.full((nu * nv, 3), 0.6 * spacing)
            s[:, axis] = 0.1 * spacing
            pts.append(p)
            scales.append(s)
    x = torch.cat(pts)
    x = x + 1e-4 * spacing * torch.randn(x.shape, generator=gen, dtype=torch.float64)
    n = len(x)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1
    sh = torch.zeros(n, 1, 3)
    return GaussianSet(x.float(), quats, torch.cat(scales), torch.full((n,), 0.9), sh)


@pytest.mark.slow
def test_thin_plate_thickness_is_measured():
    """A plate 0.5 m wide and 30 mm thick: the probe's thin parts are as thick as the plate (within a probe voxel
    of 0.5/128 m either way), and a 120 mm block reads about four times thicker."""
    plate = box_surface((0.25, 0.25, 0.4), (0.75, 0.75, 0.43), 0.004)
    thin, _ = probe(plate, 0.5, 0.2, 0.01, 1)
    h = 0.5 / 128
    assert abs(thin - 0.03) <= 1.5 * h, thin
    block = box_surface((0.25, 0.25, 0.4), (0.75, 0.75, 0.52), 0.006)
    thick, _ = probe(block, 0.5, 0.2, 0.01, 1)
    assert 3.0 < thick / thin < 5.0, (thick, thin)


@pytest.mark.slow
def test_resolution_resolves_thin_parts_within_the_budget():
    """Δx = half the thin parts' thickness within the quality's bounds (two cells across, or finer); a part too thin
    for the CPU's budget is reported as under-resolved, and the GPU's budget goes finer."""
    plate = box_surface((0.25, 0.25, 0.4), (0.75, 0.75, 0.43), 0.004)
    cap = CaptureConfig()
    lo, hi, _ = BUDGETS["cuda"]["default"]
    gpu = choose(plate, cap, "cuda:0")
    assert gpu.cells == min(max(math.ceil(2 * 0.5 / gpu.thin), lo), hi), "two cells across the thin parts"
    assert gpu.thin / gpu.dx >= 2.0
    cpu = choose(plate, cap, "cpu")
    assert cpu.cells <= BUDGETS["cpu"]["default"][1] and cpu.dx > gpu.dx
    foil = box_surface((0.25, 0.25, 0.4), (0.75, 0.75, 0.404), 0.004)
    cap.quality = "draft"
    under = choose(foil, cap, "cpu")
    assert under.thin < under.dx and "under-resolved" in under.note and 'quality = "fine"' in under.note
    cap.quality, cap.cells_across = "default", 40
    given = choose(plate, cap, "cpu")
    assert given.cells == 40 and given.dx == pytest.approx(0.5 / 40) and "capture.cells_across" in given.note


@pytest.mark.slow
def test_particle_count_follows_the_spacing_not_the_gaussians():
    """Four times the Gaussians on the same surface give the same number of simulated particles (one per voxel
    of the spacing), and every Gaussian is carried by its nearest particle."""
    coarse = box_surface((0.3, 0.3, 0.3), (0.7, 0.6, 0.5), 0.004)
    dense = box_surface((0.3, 0.3, 0.3), (0.7, 0.6, 0.5), 0.002)
    a, _ = sample(coarse, 0.02)
    b, note = sample(dense, 0.02)
    na, nb = len(a.carrier.particles), len(b.carrier.particles)
    assert len(dense) > 3.5 * len(coarse)
    assert abs(na - nb) <= 0.1 * na, (na, nb)
    assert nb < len(dense) / 10 and "carrying all" in note
    px = b.carrier.particles.means.double()
    d = torch.cdist(b.means.double(), px)
    assert torch.equal(d.argmin(1), b.carrier.index) or bool(
        (d.gather(1, b.carrier.index[:, None])[:, 0] <= d.min(1).values + 1e-9).all()
    )


def test_carried_gaussians_move_with_their_particle():
    """Under a rigid motion of every particle (x → R x + t, F = R) each carried Gaussian moves rigidly too:
    x_g = R x⁰_g + t exactly, and its F is R."""
    dense = box_surface((0.3, 0.3, 0.3), (0.7, 0.6, 0.5), 0.003)
    gs, _ = sample(dense, 0.02)
    c = gs.carrier
    ang = 0.7
    R = torch.tensor([[math.cos(ang), -math.sin(ang), 0], [math.sin(ang), math.cos(ang), 0], [0, 0, 1.0]])
    t = torch.tensor([0.1, -0.2, 0.05])
    x = c.particles.means @ R.T + t
    F = R.expand(len(x), 3, 3)
    means, Fg = c.carry(x, F)
    torch.testing.assert_close(means, gs.means @ R.T + t, atol=2e-6, rtol=0)
    torch.testing.assert_close(Fg, R.expand(len(gs), 3, 3))


def test_sparse_sets_are_simulated_whole():
    """A set no denser than the particle spacing is not sampled: every Gaussian is a particle."""
    sparse = box_surface((0.3, 0.3, 0.3), (0.7, 0.6, 0.5), 0.05)
    gs, note = sample(sparse, 0.02)
    assert gs.carrier is None and "all" in note


def test_wave_speed_and_presets_stand_and_break():
    """c = √((λ + 2μ)/ρ) equals the textbook √(E(1−ν)/((1+ν)(1−2ν)ρ)); every stiff preset bears its own weight
    at 0.5 m (σ_R > 2 ρ g H) and breaks under a 1.5 m/s impact (ρ c v > σ_R)."""
    for name, p in PRESETS.items():
        c = math.sqrt(p.E * (1 - p.nu) / ((1 + p.nu) * (1 - 2 * p.nu) * p.density))
        assert p.wave_speed == pytest.approx(c, rel=1e-12)
        if name != "bread":
            assert p.sigma_R > 2 * p.density * 9.8 * 0.5, name
            assert p.density * p.wave_speed * 1.5 > p.sigma_R, name


def test_material_preset_is_written_and_config_keeps_it():
    """`capture.material = "wood"` writes wood's constants into [material] and marks the config `config`, so a
    rerun of the written config keeps them; `config` leaves [material] untouched."""
    cfg = SceneConfig()
    cfg.capture.material = "wood"
    note = apply_material(cfg, 0.5)
    w = PRESETS["wood"]
    assert (cfg.material.E, cfg.material.density, cfg.material.sigma_R) == (w.E, w.density, w.sigma_R)
    assert cfg.capture.material == "config" and cfg.render.interior_rgb == w.interior_rgb
    assert "material wood" in note and "wave speed" in note
    cfg.material.E = 1234.0
    apply_material(cfg, 0.5)
    assert cfg.material.E == 1234.0


def test_auto_roi_keeps_thin_extremities_and_drops_what_is_apart():
    """A body with a thin rod sticking out (0.5 % of the Gaussians, beyond the 99th percentile along x) stays one
    object; a cluster 2 m away is background."""
    gen = torch.Generator().manual_seed(0)
    body = torch.rand(20000, 3, generator=gen, dtype=torch.float64) * torch.tensor([1.0, 0.5, 0.5])
    rod = torch.stack(
        [1.0 + torch.linspace(0, 0.6, 100, dtype=torch.float64), torch.full((100,), 0.25), torch.full((100,), 0.25)], 1
    )
    far = torch.rand(150, 3, generator=gen, dtype=torch.float64) * 0.1 + torch.tensor([3.5, 0.0, 0.0])
    lo, hi = auto_roi(torch.cat([body, rod, far]), 1.0)
    assert float(hi[0]) >= 1.6, "the rod's tip is inside"
    assert float(hi[0]) < 3.0, "the far cluster is outside"


def two_halves(spacing=0.01):
    """Particles on a lattice in [0, 0.2]³, fragment 0 below x = 0.1 and 1 above; the Gaussians are the particles."""
    g = torch.arange(0, 0.2 + 1e-9, spacing, dtype=torch.float64)
    x = torch.stack(torch.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    frag = (x[:, 0] > 0.1 - 1e-9).to(torch.int32)
    return x, frag


def test_crack_faces_trim_gaussians_to_their_own_side():
    """Isotropic Gaussians of σ = 8 mm on a 10 mm lattice cut at x = 0.1: next to the cut, each one's extent across
    it (2σ_x) shrinks to its distance from the bisector of its particle and the nearest one across (5 mm, or
    S_MIN·σ), its extent along the cut stays 8 mm, and Gaussians two cells or more from the cut are unchanged."""
    x, frag = two_halves()
    sigma = 0.008
    cov0 = (sigma**2 * torch.eye(3, dtype=torch.float64)).expand(len(x), 3, 3).clone()
    faces = CrackFaces(x, cov0, x, None)
    out = faces.trimmed(frag)
    near = (x[:, 0] - 0.095).abs() < 0.006  # the two lattice planes beside the cut (x = 0.09 and x = 0.10)
    sx = out[:, 0, 0].sqrt()
    d = 0.005  # half the lattice spacing
    expect = max(d / (2 * sigma), S_MIN) * sigma
    torch.testing.assert_close(sx[near], torch.full_like(sx[near], expect), rtol=1e-6, atol=1e-9)
    torch.testing.assert_close(out[near][:, 1, 1].sqrt(), torch.full_like(sx[near], sigma), rtol=1e-9, atol=0)
    far = (x[:, 0] - 0.1).abs() > 0.025
    assert torch.equal(out[far], cov0[far])
    assert faces.trimmed_count == int(near.sum())
    assert torch.equal(faces.trimmed(torch.full_like(frag, -1)), cov0), "no fragments, nothing trimmed"


@pytest.mark.slow
def test_a_carried_capture_simulates_its_particles(tmp_path):
    """Through the pipeline, a capture with more Gaussians than its grid needs simulates only the carrier's
    particles, and frame 0 puts every drawn Gaussian exactly where the capture has it."""
    from trainer_ply import write_trainer_ply

    from fracture_gs.io.config import load_config
    from fracture_gs.pipeline import make_simulator, prepare_scene, simulate

    ply, _ = write_trainer_ply(tmp_path, n=9000)
    cfg = load_config(ply)
    cfg.capture.cells_across, cfg.frames = 12, 1
    scene = prepare_scene(cfg, "cpu")
    gs = scene.gaussians
    assert gs.carrier is not None and len(gs.carrier.particles) < len(gs) / 2
    sim = make_simulator(scene.cfg, gs, "full", "cpu")
    assert len(sim.particles) == len(gs.carrier.particles)
    first = next(iter(simulate(sim, gs.covariances().float(), 1, scene.cfg.frame_dt, carrier=gs.carrier)))
    assert first.means.shape == gs.means.shape
    torch.testing.assert_close(first.means, gs.means.float(), atol=1e-6, rtol=0)


@pytest.mark.slow
def test_material_regions_set_the_particles_material(tmp_path):
    """A `[[capture.regions]]` box of wood on a ceramic capture: the simulated particles inside it get wood's
    Young's modulus and density, those outside keep ceramic's, and resolving the written config again adds no
    second material_map entry."""
    from trainer_ply import write_trainer_ply

    from fracture_gs.config import MaterialRegion
    from fracture_gs.io.config import dump_config, load_config
    from fracture_gs.io.ply import load_ply
    from fracture_gs.pipeline import make_simulator, prepare_scene

    ply, _ = write_trainer_ply(tmp_path, n=9000)
    cfg = load_config(ply)
    cfg.capture.cells_across = 12
    x = float(load_ply(ply).means[:, 0].median())  # the PLY's own coordinates: the box holds half its Gaussians
    big = 1e3
    cfg.capture.regions = [MaterialRegion(lower=(x, -big, -big), upper=(big, big, big), material="wood")]
    scene = prepare_scene(cfg, "cpu")
    sim = make_simulator(scene.cfg, scene.gaussians, "full", "cpu")
    E, rho = sim.particles.E, sim.particles.mass / sim.particles.volume
    wood, ceramic = PRESETS["wood"], PRESETS["ceramic"]
    is_wood = E == wood.E
    assert 0.25 < float(is_wood.float().mean()) < 0.75, "about half the particles lie in the box"
    assert bool((E[~is_wood] == ceramic.E).all())
    torch.testing.assert_close(rho[is_wood], torch.full_like(rho[is_wood], wood.density))
    again = tmp_path / "again.toml"
    again.write_text(dump_config(scene.cfg))
    rerun = prepare_scene(load_config(again), "cpu")
    assert len(rerun.cfg.material_map) == len(scene.cfg.material_map) == 1


def test_covariances_factor_in_chunks(monkeypatch):
    """Export factors Σ = R diag(s²) Rᵀ for more matrices than one eigh batch takes (cuSOLVER failed on a 110k
    capture): with the chunk made small, 10 chunks give back every covariance to round-off."""
    import fracture_gs.linalg as linalg
    from fracture_gs.capture.transform import gaussians_from_covariances
    from fracture_gs.io.gaussian_set import quat_to_matrix

    monkeypatch.setattr(linalg, "EIGH_CHUNK", 100)
    gen = torch.Generator().manual_seed(1)
    A = torch.randn(1000, 3, 3, generator=gen, dtype=torch.float64)
    cov = A @ A.transpose(1, 2) + 1e-3 * torch.eye(3, dtype=torch.float64)
    q, s = gaussians_from_covariances(cov)
    R = quat_to_matrix(q)
    torch.testing.assert_close(R @ torch.diag_embed(s**2) @ R.transpose(1, 2), cov, rtol=1e-9, atol=1e-12)


def test_limit_stretch_clamps_principal_stretches_and_keeps_rotation():
    """F = R diag(2, 1, 0.4): with s_max = 1.25 the drawn F is R diag(1.25, 1, 0.8) (singular values clamped, the
    same rotation, so Σ = F Σ⁰ Fᵀ is bounded); an F within the band is returned untouched, bit for bit."""
    from fracture_gs.render.gaussians import limit_stretch

    ang = 0.4
    R = torch.tensor([[math.cos(ang), -math.sin(ang), 0], [math.sin(ang), math.cos(ang), 0], [0, 0, 1.0]])
    F = torch.stack([R @ torch.diag(torch.tensor([2.0, 1.0, 0.4])), R @ torch.diag(torch.tensor([1.05, 1.0, 0.97]))])
    out = limit_stretch(F, 1.25)
    torch.testing.assert_close(out[0], R @ torch.diag(torch.tensor([1.25, 1.0, 0.8])), atol=1e-6, rtol=0)
    assert torch.equal(out[1], F[1])


def test_ground_is_found_under_an_object_and_nowhere_else():
    """A wide flat layer (the pavement, 60 % of the Gaussians) under a box: its top is found between the layer and
    the box's base; the box alone, or the layer alone, has no ground."""
    from fracture_gs.capture.ground import find_ground

    gen = torch.Generator().manual_seed(3)
    up = torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64)  # COLMAP: up is −y
    floor = torch.rand(30000, 3, generator=gen, dtype=torch.float64) * torch.tensor([4.0, 0.01, 4.0])
    floor[:, 1] += 1.0  # at y ≈ 1.0 (height −1.0)
    box = torch.rand(20000, 3, generator=gen, dtype=torch.float64) * torch.tensor([1.0, 1.0, 1.0])
    box += torch.tensor([1.5, -0.0, 1.5])  # y in [0, 1]: height from −1 (on the floor) up to 0
    level = find_ground(torch.cat([floor, box]), up)
    assert level is not None and -1.01 < level < -0.9, level
    assert find_ground(box, up) is None
    assert find_ground(floor, up) is None


def test_the_wide_bottom_of_an_object_is_not_ground():
    """A cone standing on its wide base (most Gaussians low down, but spread over many heights) has no ground: the
    ground is a spike in the heights, not a broad bottom."""
    from fracture_gs.capture.ground import find_ground

    gen = torch.Generator().manual_seed(4)
    u = torch.rand(60000, generator=gen, dtype=torch.float64)
    height = 1.0 - torch.sqrt(u)  # dense near the base, thinning to the tip
    r = (1.0 - height) * torch.rand(60000, generator=gen, dtype=torch.float64).sqrt()
    a = 2 * math.pi * torch.rand(60000, generator=gen, dtype=torch.float64)
    x = torch.stack([r * torch.cos(a), -height, r * torch.sin(a)], 1)  # up is −y
    assert find_ground(x, torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64)) is None
