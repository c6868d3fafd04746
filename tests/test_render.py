"""Renderer tests (CPU): Gaussian update from F, SH, cameras, torch rasterizer vs float64 reference,
projection vs gsplat's pure-torch helpers. Every random test draws a fresh seed and prints it."""

from __future__ import annotations

import math
import os
import random
import subprocess
import sys
import time

import numpy as np
import pytest
import torch
from imageutil import check_object_where_projected
from torch.testing import assert_close

from fracture_gs.config import CameraConfig
from fracture_gs.render import (
    Camera,
    deform_covariances,
    exposed_interior_colors,
    from_config,
    look_at,
    orbit,
    polar_rotation,
    project_gaussians,
    render,
    render_reference,
    sh_colors,
    visible_mask,
)
from fracture_gs.render.gaussians import sh_basis


def fresh_seed() -> tuple[int, torch.Generator]:
    """A fresh seed per test (FGS_SEED=<seed> reproduces a failure) and a generator seeded with it."""
    seed = int(os.environ.get("FGS_SEED", random.SystemRandom().randrange(2**31)))
    return seed, torch.Generator().manual_seed(seed)


def random_rotations(n, g, dtype=torch.float64):  # [n,3,3], det +1
    Q, Rr = torch.linalg.qr(torch.randn(n, 3, 3, generator=g, dtype=dtype))
    Q = Q * torch.sign(torch.diagonal(Rr, dim1=-2, dim2=-1))[:, None, :]
    Q[:, :, 2] *= torch.sign(torch.linalg.det(Q))[:, None]
    return Q


def random_spd(n, g, lo=0.2, hi=2.0, dtype=torch.float64):  # [n,3,3]
    Q = random_rotations(n, g, dtype)
    ev = lo + (hi - lo) * torch.rand(n, 3, generator=g, dtype=dtype)
    return Q @ torch.diag_embed(ev) @ Q.transpose(1, 2)


def random_scene(n, g, spread=0.4, scale=0.05, sh_degree=0, dtype=torch.float32):
    """Gaussians around the origin: means, rest covariances, SH, opacities."""
    means = spread * torch.randn(n, 3, generator=g)
    Q = random_rotations(n, g).float()
    s = scale * torch.exp(0.6 * torch.randn(n, 3, generator=g))
    M = Q * s[:, None, :]
    cov = M @ M.transpose(1, 2)
    sh = 0.4 * torch.randn(n, (sh_degree + 1) ** 2, 3, generator=g)
    opac = 0.05 + 0.95 * torch.rand(n, generator=g)
    return [t.to(dtype) for t in (means, cov, sh, opac)]


# ---------------------------------------------------------------- Gaussian update from F


def test_deform_covariances_is_F_cov_Ft_and_spd():
    """The deformed Gaussian is the image of the rest ellipsoid under x ↦ F x, checked against closed forms
    computed here: a scale-only F = diag(k) scales the axes of an axis-aligned Σ⁰ = diag(s²) to diag((k s)²); a
    rotation Q turns it into the ellipsoid whose axes are Q's columns with the same lengths (Σ q_i = s_i² q_i);
    a simple shear of a sphere σ² I gives σ² [[1 + γ², γ, 0], [γ, 1, 0], [0, 0, 1]]. For random F the level
    sets map: (F y)ᵀ Σ⁻¹ (F y) = yᵀ Σ⁰⁻¹ y for any y, and det Σ = det² F · det Σ⁰; the result is symmetric and
    SPD (also in float32 while cond F ≤ 100)."""
    seed, g = fresh_seed()
    msg = lambda m: f"seed {seed}: {m}"  # noqa: E731
    d = torch.float64
    s = torch.tensor([0.01, 0.03, 0.002], dtype=d)
    k = torch.tensor([2.0, 0.5, 3.0], dtype=d)
    scaled = deform_covariances(torch.diag(k)[None], torch.diag(s**2)[None])[0]
    assert_close(scaled, torch.diag(torch.tensor([0.02, 0.015, 0.006], dtype=d) ** 2), msg=msg)
    Q = random_rotations(1, g)[0]
    turned = deform_covariances(Q[None], torch.diag(s**2)[None])[0]
    for i in range(3):
        assert_close(turned @ Q[:, i], s[i] ** 2 * Q[:, i], rtol=0, atol=1e-15, msg=msg)
    gamma, sigma2 = 0.7, 0.04**2
    shear = torch.tensor([[1.0, gamma, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], dtype=d)
    sheared = deform_covariances(shear[None], sigma2 * torch.eye(3, dtype=d)[None])[0]
    expect = sigma2 * torch.tensor([[1 + gamma**2, gamma, 0.0], [gamma, 1.0, 0.0], [0.0, 0.0, 1.0]], dtype=d)
    assert_close(sheared, expect, msg=msg)

    n = 500
    F = torch.randn(n, 3, 3, generator=g, dtype=d) + 2 * torch.eye(3, dtype=d)
    F[torch.linalg.det(F) < 0, :, 0] *= -1  # det F > 0 (physical)
    cov0 = random_spd(n, g, 1e-4, 1e-2)
    cov = deform_covariances(F, cov0)
    y = torch.randn(n, 3, generator=g, dtype=d)
    Fy = (F @ y[..., None])[..., 0]
    q_def = (Fy * torch.linalg.solve(cov, Fy)).sum(1)
    q_rest = (y * torch.linalg.solve(cov0, y)).sum(1)
    assert_close(q_def, q_rest, rtol=1e-6, atol=0, msg=msg)  # a wrong formula is off by O(1); near-singular F
    assert_close(torch.linalg.det(cov), torch.linalg.det(F) ** 2 * torch.linalg.det(cov0), rtol=1e-6, atol=0, msg=msg)
    assert_close(cov, cov.transpose(1, 2), rtol=0, atol=0, msg=lambda m: f"seed {seed}: not symmetric {m}")
    assert (torch.linalg.eigvalsh(cov) > 0).all(), f"seed {seed}: not SPD"
    # float32 keeps SPD while cond(F Σ⁰ Fᵀ) stays well under 1/ε₃₂ ≈ 1.7e7 (cond Σ⁰ ≤ 100 here, so cond F ≤ 100)
    sv = torch.linalg.svdvals(F)
    ok = sv[:, 0] / sv[:, 2] < 100
    cov32 = deform_covariances(F[ok].float(), cov0[ok].float())
    assert (torch.linalg.eigvalsh(cov32.double()) > 0).all(), f"seed {seed}: float32 result not SPD"


def test_polar_rotation_recovers_rotation_factor():
    """F = Q U (U SPD, possibly nearly singular) ⇒ polar_rotation(F) = Q."""
    seed, g = fresh_seed()
    n = 400
    Q = random_rotations(n, g)
    U = random_spd(n, g, 0.3, 3.0)
    U[: n // 4] = random_spd(n // 4, g, 0.5, 1.0) @ torch.diag(torch.tensor([1.0, 1.0, 1e-7], dtype=torch.float64))
    U[: n // 4] = 0.5 * (U[: n // 4] + U[: n // 4].transpose(1, 2))
    U[: n // 4] = U[: n // 4] + 1e-9 * torch.eye(3, dtype=torch.float64)  # SPD, condition ~1e9
    R = polar_rotation(Q @ U)
    assert_close(R, Q, rtol=0, atol=1e-6, msg=lambda m: f"seed {seed}: {m}")
    R32 = polar_rotation((Q @ U).float())
    assert R32.dtype == torch.float32
    assert_close(R32.double(), Q, rtol=0, atol=1e-4, msg=lambda m: f"seed {seed}: float32 {m}")


def test_polar_rotation_is_svd_polar_and_proper_under_reflection():
    seed, g = fresh_seed()
    n = 600
    F = torch.randn(n, 3, 3, generator=g, dtype=torch.float64)
    F[:50] = F[:50] * torch.tensor([1.0, 1.0, 1e-8], dtype=torch.float64)  # near-singular
    R = polar_rotation(F)
    I = torch.eye(3, dtype=torch.float64).expand(n, 3, 3)
    assert_close(R.transpose(1, 2) @ R, I, rtol=0, atol=1e-10, msg=lambda m: f"seed {seed}: {m}")
    assert_close(torch.linalg.det(R), torch.ones(n, dtype=torch.float64), msg=lambda m: f"seed {seed}: {m}")
    # numpy SVD polar: W diag(1, 1, det(W Vᵀ)) Vᵀ (the closest proper rotation)
    W, _, Vt = np.linalg.svd(F.numpy())
    d = np.linalg.det(W @ Vt)
    D = np.ones((n, 3))
    D[:, 2] = d
    ref = torch.from_numpy((W * D[:, None, :]) @ Vt)
    well = torch.arange(n) >= 50  # near-singular F with det<0 has no unique answer; check only properness
    assert_close(R[well], ref[well], rtol=0, atol=1e-8, msg=lambda m: f"seed {seed}: {m}")
    pos = (torch.linalg.det(F) > 0) & well
    # for det F > 0 the polar rotation is the unconstrained closest orthogonal matrix W Vᵀ
    assert_close(R[pos], torch.from_numpy(W @ Vt)[pos], rtol=0, atol=1e-8, msg=lambda m: f"seed {seed}: {m}")


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_sh_basis_matches_gsplat(degree):
    from gsplat.cuda._torch_impl import _spherical_harmonics

    seed, g = fresh_seed()
    n = 300
    coeffs = torch.randn(n, (degree + 1) ** 2, 3, generator=g, dtype=torch.float64)
    dirs = torch.nn.functional.normalize(torch.randn(n, 3, generator=g, dtype=torch.float64), dim=-1)
    ref = _spherical_harmonics(degree, dirs, coeffs)
    ours = torch.einsum("nk,nkc->nc", sh_basis(dirs, degree), coeffs)
    assert_close(ours, ref, msg=lambda m: f"seed {seed}: {m}")
    # sh_colors = clamp(SH(d) + 0.5, 0) with d from the camera centre
    means = torch.randn(n, 3, generator=g, dtype=torch.float64)
    campos = torch.tensor([0.3, -4.0, 1.0], dtype=torch.float64)
    col = sh_colors(coeffs, means, campos)
    assert_close(
        col,
        (_spherical_harmonics(degree, means - campos, coeffs) + 0.5).clamp_min(0),
        msg=lambda m: f"seed {seed}: {m}",
    )


def test_rigid_rotation_renders_like_inverse_rotated_camera():
    """F = Q, x = Q x₀ seen from camera (V, c) ≡ the rest body seen from (V·Q, Qᵀc), SH included."""
    seed, g = fresh_seed()
    n = 150
    x0, cov0, sh, opac = random_scene(n, g, spread=0.3, scale=0.06, sh_degree=3, dtype=torch.float64)
    sh = 2.0 * sh  # strong view dependence
    Q = random_rotations(1, g)[0]
    cam = look_at((0.2, -2.0, 0.7), (0, 0, 0), (0, 0, 1), 45, 48, 40).to(dtype=torch.float64)
    F = Q.expand(n, 3, 3)
    x = x0 @ Q.T
    img_rot = render(
        x, deform_covariances(F, cov0), sh_colors(sh, x, cam.campos, polar_rotation(F)), opac, cam, backend="torch"
    ).image
    V = cam.viewmat.clone()
    V[:3, :3] = V[:3, :3] @ Q
    cam0 = Camera(V, cam.K, cam.width, cam.height)
    assert_close(cam0.campos, Q.T @ cam.campos)
    img_rest = render(x0, cov0, sh_colors(sh, x0, cam0.campos), opac, cam0, backend="torch").image
    assert img_rest.std() > 0.05, f"seed {seed}: empty image"
    assert_close(img_rot, img_rest, rtol=0, atol=1e-9, msg=lambda m: f"seed {seed}: {m}")
    # the test is sensitive: without rotating the view direction the images differ
    img_norot = render(
        x, deform_covariances(F, cov0), sh_colors(sh, x, cam.campos, None), opac, cam, backend="torch"
    ).image
    assert (img_norot - img_rest).abs().max() > 1e-2, f"seed {seed}: SH rotation has no effect"


@pytest.mark.slow
def test_exposed_interior_colors_and_visible_mask():
    seed, g = fresh_seed()
    inner, surf = torch.randn(333, 3, generator=g), torch.randn(250, 3, generator=g)
    cols = torch.rand(250, 3, generator=g)
    got = exposed_interior_colors(inner, surf, cols, chunk=7)
    ref = cols[torch.cdist(inner.double(), surf.double()).argmin(dim=1)]
    assert_close(got, ref, msg=lambda m: f"seed {seed}: {m}")
    interior = torch.tensor([False, False, True, True])
    exposed = torch.tensor([False, True, False, True])
    assert visible_mask(interior, exposed, True).tolist() == [True, True, False, True]
    assert visible_mask(interior, exposed, False).tolist() == [True, True, False, False]


# ---------------------------------------------------------------- cameras


def test_camera_conventions():
    cam = look_at((1.0, -3.0, 0.5), (1.0, 0.0, 0.5), (0, 0, 1), 60, 64, 48)
    assert_close(cam.campos, torch.tensor([1.0, -3.0, 0.5]))
    R = cam.viewmat[:3, :3]
    assert_close(R @ R.T, torch.eye(3), atol=1e-6, rtol=0)
    pts = torch.tensor([[1.0, 0.0, 0.5], [1.0, 0.0, 1.5], [2.0, 0.0, 0.5]])
    uv, z = cam.project(pts)
    assert_close(uv[0], torch.tensor([32.0, 24.0]))  # target at the image centre
    assert_close(z, torch.full((3,), 3.0))
    assert uv[1, 1] < uv[0, 1], "world up must be image up (OpenCV: y down)"
    assert uv[2, 0] > uv[0, 0], "x right"
    f = 24 / math.tan(math.radians(30))
    assert_close(cam.K, torch.tensor([[f, 0, 32], [0, f, 24], [0, 0, 1.0]]))
    assert abs(cam.fov_deg - 60) < 1e-4


def test_orbit_and_from_config():
    cam = orbit((0.5, 0.5, 0.3), 2.0, 30.0, 90.0, (0, 0, 1), 40, 32, 32)
    expect = torch.tensor([0.5, 0.5 + 2 * math.cos(math.radians(30)), 0.3 + 2 * math.sin(math.radians(30))])
    assert_close(cam.campos, expect, atol=1e-5, rtol=0)
    cfg = CameraConfig(eye=(0.5, -1.5, 0.6), target=(0.5, 0.5, 0.3), up=(0, 0, 1), fov_deg=40, orbit_degrees=90)
    c0, c1 = from_config(cfg, 32, 32, 0.0), from_config(cfg, 32, 32, 1.0)
    assert_close(c0.campos, torch.tensor([0.5, -1.5, 0.6]), atol=1e-6, rtol=0)
    assert_close(c1.campos, torch.tensor([2.5, 0.5, 0.6]), atol=1e-5, rtol=0)  # +90° about z through target
    for c in (c0, c1):
        uv, z = c.project(torch.tensor([[0.5, 0.5, 0.3]]))
        assert_close(uv[0], torch.tensor([16.0, 16.0]), atol=1e-4, rtol=0)
        assert z[0] > 0


# ---------------------------------------------------------------- projection and rasterization


def _cross_check_scene(g, n=400):
    means, cov, _, opac = random_scene(n, g, spread=1.0, scale=0.08, dtype=torch.float64)
    means[:40, 0] *= 6  # far outside the frustum: exercises the 1.3·tan(fov/2) clamp of J
    means[40:60, 1] = -4.0  # behind / at the camera
    return means, cov, opac


@pytest.mark.parametrize("mode", ["classic", "antialiased"])
def test_projection_matches_gsplat_torch_impl(mode):
    from gsplat.cuda._torch_impl import _fully_fused_projection

    seed, g = fresh_seed()
    means, cov, _ = _cross_check_scene(g)
    cam = look_at((0.1, -3.0, 0.4), (0, 0, 0), (0, 0, 1), 50, 80, 60).to(dtype=torch.float64)
    cam.K[0, 2] += 3.7  # off-centre principal point: asymmetric clamp limits
    radii, m2d, depths, conics, comp = _fully_fused_projection(
        means,
        cov,
        cam.viewmat[None],
        cam.K[None],
        cam.width,
        cam.height,
        eps2d=0.3,
        near_plane=0.01,
        far_plane=1e10,
        calc_compensations=mode == "antialiased",
    )
    p = project_gaussians(means, cov, cam.viewmat, cam.K, cam.width, cam.height, 0.3, 0.01, 1e10, mode, None)
    ok = (radii[0] > 0).all(-1)
    msg = lambda m: f"seed {seed}: {m}"
    assert ok.sum() > 100, msg("too few visible")
    assert torch.equal(p.radii, radii[0].int()), msg("radii differ")
    assert_close(p.means2d[ok], m2d[0][ok], msg=msg)
    assert_close(p.depths, depths[0], msg=msg)
    assert_close(p.conics[ok], conics[0][ok], msg=msg)
    if mode == "antialiased":
        assert_close(p.compensations[ok], comp[0][ok], msg=msg)


def _threshold_ambiguous(means, cov, opac, cam, mode, pixels, rel=1e-4):
    """For each pixel (row, col): does some compositing decision at it (α ≥ 1/255, T(1−α) ≤ 1e-4)
    sit within `rel` of its threshold in float64, so float32 rounding may flip it?"""
    f = lambda t: t.double()
    p = project_gaussians(
        f(means), f(cov), f(cam.viewmat), f(cam.K), cam.width, cam.height, 0.3, 0.01, 1e10, mode, None
    )
    ids = torch.nonzero((p.depths >= 0.01) & (torch.linalg.det(p.covars2d) > 0)).squeeze(1)
    ids = ids[torch.sort(p.depths[ids], stable=True).indices]
    o = f(opac) * (p.compensations if mode == "antialiased" else 1.0)
    out = []
    for r, c in pixels:
        d = p.means2d[ids] - torch.tensor([c + 0.5, r + 0.5], dtype=torch.float64)
        a, b, cc = p.conics[ids].unbind(-1)
        alpha = o[ids] * torch.exp(-(0.5 * (a * d[:, 0] ** 2 + cc * d[:, 1] ** 2) + b * d[:, 0] * d[:, 1]))
        alpha = alpha.clamp_max(0.999)
        T, near = 1.0, False
        for al in alpha.tolist():
            near |= abs(al * 255.0 - 1.0) < rel
            if al < 1 / 255:
                continue
            near |= abs(T * (1 - al) / 1e-4 - 1.0) < rel
            if T * (1 - al) <= 1e-4:
                break
            T *= 1 - al
        out.append(near)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["classic", "antialiased"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_torch_backend_matches_float64_reference(mode, dtype):
    """Tile rasterizer vs the per-pixel float64 reference: ≤ 1e-4 everywhere (1e-10 in float64).
    In float32 a pixel may differ more only where a threshold decision (α vs 1/255, T vs 1e-4) lies
    within float32 rounding of its boundary; such pixels are verified to be exactly those."""
    seed, g = fresh_seed()
    n = 160
    means, cov, _, opac = random_scene(n, g, spread=0.35, scale=0.05)
    cols = torch.rand(n, 3, generator=g)
    eye = torch.tensor([0.05, -2.0, 0.3])
    # an opaque stack on the view axis: its pixels reach T ≤ 1e-4 and stop early
    means[:12] = 0.3 * eye + 0.003 * torch.randn(12, 3, generator=g)
    cov[:12] = 0.04**2 * torch.eye(3)
    opac[:12] = 0.99
    means[12:20, 1] = -2.5  # behind the camera
    cov[20:30] *= 30.0  # a few big, soft Gaussians
    cam = look_at(eye.tolist(), (0, 0, 0), (0, 0, 1), 45, 61, 45)  # sizes not multiples of 16
    bg = (0.2, 0.6, 1.0)
    ref = render_reference(means, cov, cols, opac, cam, bg, mode)
    out = render(means.to(dtype), cov.to(dtype), cols.to(dtype), opac.to(dtype), cam, bg, "torch", mode)
    assert out.backend == "torch" and out.image.shape == (45, 61, 3) and out.alpha.shape == (45, 61)
    assert (ref.alpha > 0.999).any() and (ref.alpha < 0.5).any(), f"seed {seed}: scene lacks stops/background"
    msg = lambda m: f"seed {seed} {mode} {dtype}: {m}"
    if dtype == torch.float64:
        assert_close(out.image, ref.image, rtol=0, atol=1e-10, msg=msg)
        assert_close(out.alpha, ref.alpha, rtol=0, atol=1e-10, msg=msg)
        return
    err = torch.maximum((out.image.double() - ref.image).abs().amax(-1), (out.alpha.double() - ref.alpha).abs())
    bad = torch.nonzero(err > 1e-4).tolist()
    assert len(bad) <= 5, msg(f"{len(bad)} pixels over 1e-4, max {err.max():.2e}")
    assert all(_threshold_ambiguous(means, cov, opac, cam, mode, bad)), msg(f"pixels {bad} differ by {err.max():.2e}")


def test_empty_and_offscreen_scenes_render_background():
    cam = look_at((0, -2, 0), (0, 0, 0), (0, 0, 1), 40, 20, 18)
    out = render(torch.zeros(0, 3), torch.zeros(0, 3, 3), torch.zeros(0, 3), torch.zeros(0), cam, (0.1, 0.2, 0.3))
    assert_close(out.image, torch.tensor([0.1, 0.2, 0.3]).expand(18, 20, 3))
    out = render(torch.tensor([[0.0, -5.0, 0.0]]), 0.01 * torch.eye(3)[None], torch.ones(1, 3), torch.ones(1), cam)
    assert_close(out.alpha, torch.zeros(18, 20))


@pytest.mark.slow
def test_backend_choice_by_device_never_imports_gsplat_on_cpu():
    cam = look_at((0, -2, 0), (0, 0, 0), (0, 0, 1), 40, 16, 16)
    args = (torch.zeros(1, 3), 0.01 * torch.eye(3)[None], torch.ones(1, 3), torch.ones(1), cam)
    assert render(*args).backend == "warp"  # CPU tensors, no gradient: the Warp kernels (test_raster_warp.py)
    with pytest.raises(ValueError, match="CUDA"):
        render(*args, backend="gsplat")
    with pytest.raises(ValueError, match="backend"):
        render(*args, backend="vulkan")
    code = (
        "import sys, torch\nfrom fracture_gs.render import render, look_at\n"
        "cam = look_at((0, -2, 0), (0, 0, 0), (0, 0, 1), 40, 16, 16)\n"
        "out = render(torch.zeros(1, 3), 0.01 * torch.eye(3)[None], torch.ones(1, 3), torch.ones(1), cam)\n"
        "assert out.backend == 'warp'\n"
        "assert not any(m.startswith('gsplat') for m in sys.modules), 'gsplat imported on CPU'\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


@pytest.mark.slow
def test_cpu_render_20k_256_draws_the_shell_where_it_projects():
    """20k Gaussians on an ellipsoidal shell at 256² with the torch backend: the pixels the means project into
    are covered, every pixel outside every Gaussian's 3σ footprint is exactly the background colour, and the
    shell's front hides its far side (alpha ≈ 1 at the image centre). Prints the CPU time per frame."""
    seed, g = fresh_seed()
    n = 20000
    means = (
        torch.nn.functional.normalize(torch.randn(n, 3, generator=g), dim=1)
        * 0.35
        * (1 + 0.15 * torch.randn(n, 1, generator=g))
        * torch.tensor([1.3, 1.0, 0.8])
    )
    Q = random_rotations(n, g).float()
    M = Q * (0.012 * torch.exp(0.5 * torch.randn(n, 3, generator=g)))[:, None, :]
    cov, opac, cols = M @ M.transpose(1, 2), 0.3 + 0.7 * torch.rand(n, generator=g), torch.rand(n, 3, generator=g)
    cam = look_at((0, -2.2, 0.6), (0, 0, 0), (0, 0, 1), 40, 256, 256)
    bg = (0.1, 0.2, 0.9)
    t0 = time.perf_counter()
    out = render(means, cov, cols, opac, cam, bg, backend="torch")  # (auto is Warp on the CPU: test_raster_warp.py)
    seconds = time.perf_counter() - t0
    sigma = torch.linalg.eigvalsh(cov.double())[:, -1].sqrt()  # [N] largest axis
    check_object_where_projected(out.image.numpy(), cam, means, sigma, bg, near_frac=0.99)
    assert float(out.alpha[128, 128]) > 0.99, f"seed {seed}: the shell's centre is not opaque"
    print(f"\n[speed] torch backend, {n} Gaussians, 256x256, {torch.get_num_threads()} threads: {seconds:.3f} s/frame")
