"""Pinned rules of the capture package (`fracture_gs.capture`): material presets, clean-up counts, the ground
finder's thresholds, splat export of a background with other SH degrees, the trainer camera, the resolution
budgets and the starter TOML's comment width.

Unit-level calls on small synthetic Gaussian sets: no simulation runs.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture import resolution, starter
from fracture_gs.capture.camera import frame_box, trainer_view
from fracture_gs.capture.clean import CleanReport, clean, outlier_mask
from fracture_gs.capture.export import export_ply
from fracture_gs.capture.fit import (
    TrainerCamera,
    detect_up,
    find_cameras_json,
    fit_transform,
    read_cameras,
    roi_mask,
    rotation_onto_z,
)
from fracture_gs.capture.ground import find_ground
from fracture_gs.capture.materials import PRESETS, apply_material, apply_regions, substep_note, wave_speed
from fracture_gs.capture.resolution import choose
from fracture_gs.capture.transform import SceneTransform
from fracture_gs.config import REGION_LABEL, CaptureConfig, MaterialRegion, SceneConfig
from fracture_gs.errors import SceneError
from fracture_gs.io.config import validate
from fracture_gs.io.formats import read_gaussians
from fracture_gs.io.gaussian_set import GaussianSet

G = 9.8  # m/s²


def gaussians(means, opacity=0.9, scale=0.01, k=1, seed=0) -> GaussianSet:
    """Isotropic Gaussians at `means` [N, 3] with random SH of K = k coefficients."""
    x = torch.as_tensor(means, dtype=torch.float32)
    n = len(x)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    sh = torch.randn(n, k, 3, generator=torch.Generator().manual_seed(seed))
    return GaussianSet(x, quats, torch.full((n, 3), scale), torch.full((n,), float(opacity)), sh)


def p_wave_closed_form(E, nu, rho):
    """c = √(E(1−ν) / (ρ(1+ν)(1−2ν))), the P-wave speed written without Lamé parameters."""
    return math.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu)))


# ---------------------------------------------------------------------------------------------
# material presets


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_interior_colour_is_a_valid_rgb(name):
    """Each preset's interior colour (drawn on crack faces) is an RGB triple with every channel in [0, 1]."""
    rgb = PRESETS[name].interior_rgb
    assert len(rgb) == 3 and all(0.0 <= c <= 1.0 for c in rgb), rgb


def test_preset_wave_speeds_and_strengths_follow_the_module_budget():
    """The presets keep the budget the module states: the stiff ones have P-wave speeds of 12–19 m/s and bread
    about 6 m/s (closed form c = √(E(1−ν)/(ρ(1+ν)(1−2ν)))); each stiff one stands under its own weight at
    0.5 m (σ_R above twice ρgH, sag ρgH/E of 1–5 %) and breaks under a 1.5 m/s impact (σ_R below ρcv)."""
    for name, p in PRESETS.items():
        c = p_wave_closed_form(p.E, p.nu, p.density)
        assert p.wave_speed == pytest.approx(c, rel=1e-12)
        assert wave_speed(p.E, p.nu, p.density) == pytest.approx(c, rel=1e-12)
        if name == "bread":
            assert 5.0 < c < 7.0
            continue
        assert 12.0 < c < 19.0, (name, c)
        self_weight = p.density * G * 0.5
        assert p.sigma_R > 2.0 * self_weight, name
        assert 0.01 <= self_weight / p.E <= 0.05, name
        assert p.sigma_R < p.density * c * 1.5, name


def test_apply_material_writes_the_preset_and_is_idempotent():
    """A preset writes its E, ν, ρ, σ_R and interior colour into the config, a failure stretch of 1 + 4σ_R/E,
    and switches capture.material to "config", so applying again keeps what was written; the result validates."""
    cfg = SceneConfig(scene="scene.ply", variants=["baseline"])  # [capture] keys act on a captured scene only
    cfg.capture.material = "wood"
    note = apply_material(cfg, 0.5)
    p = PRESETS["wood"]
    m = cfg.material
    assert (m.model, m.E, m.nu, m.density, m.sigma_R) == ("fixed_corotated", p.E, p.nu, p.density, p.sigma_R)
    assert cfg.render.interior_rgb == p.interior_rgb
    assert cfg.render.max_stretch == pytest.approx(1.0 + 4.0 * 1.0e4 / 1.5e5)
    assert cfg.capture.material == "config"
    assert f"{p_wave_closed_form(p.E, p.nu, p.density):.1f} m/s" in note
    assert f"{100 * p.density * G * 0.5 / p.E:.1f} %" in note
    before = (m.E, m.density)
    assert "as written" in apply_material(cfg, 0.5)
    assert (cfg.material.E, cfg.material.density) == before
    validate(cfg)


@pytest.mark.parametrize("sim_dt, expected", [(1e-3, None), (1e-5, 1000)])
def test_substep_note_counts_substeps_of_the_smaller_step(sim_dt, expected):
    """The note's substeps per frame are ⌈frame_dt / min(CFL step, sim.dt)⌉ with the CFL step cfl·Δx/c."""
    cfg = SceneConfig()
    cfg.material.E, cfg.material.nu, cfg.material.density = 4.0e5, 0.25, 2000.0
    cfg.sim.cfl, cfg.sim.dx, cfg.sim.dt, cfg.frame_dt = 0.4, 0.01, sim_dt, 0.01
    cfl_step = 0.4 * 0.01 / p_wave_closed_form(4.0e5, 0.25, 2000.0)  # ≈ 2.58e-4 s
    n = expected if expected is not None else math.ceil(0.01 / cfl_step)
    assert f"about {n} substeps a frame" in substep_note(cfg)


def test_material_regions_label_the_gaussians_inside_their_box():
    """Each capture region labels the Gaussians inside its box (faces included) REGION_LABEL + i and adds one
    material-map entry with its preset; applying the regions again adds no second entry."""
    cfg = SceneConfig()
    cfg.capture.regions = [
        MaterialRegion((0.0, 0.0, 0.0), (0.5, 1.0, 1.0), "wood"),
        MaterialRegion((0.875, 0.0, 0.0), (1.0, 1.0, 1.0), "bread"),
    ]
    gs = gaussians([[0.1, 0.5, 0.5], [0.5, 0.5, 0.5], [0.7, 0.5, 0.5], [0.95, 0.5, 0.5], [0.875, 0.0, 0.0]])
    apply_regions(cfg, gs)
    assert gs.labels.tolist() == [REGION_LABEL, REGION_LABEL, 0, REGION_LABEL + 1, REGION_LABEL + 1]
    apply_regions(cfg, gs)
    entries = {e.label: e for e in cfg.material_map}
    assert sorted(entries) == [REGION_LABEL, REGION_LABEL + 1] and len(cfg.material_map) == 2
    assert entries[REGION_LABEL + 1].E == PRESETS["bread"].E


# ---------------------------------------------------------------------------------------------
# clean-up


def test_clean_report_starts_at_zero_removed():
    """A fresh report of N Gaussians keeps all N and its line says nothing was removed."""
    r = CleanReport(total=7)
    assert (r.broken, r.faint, r.outliers, r.kept) == (0, 0, 0, 7)
    assert r.line() == "kept 7 of 7 Gaussians (removed 0 broken, 0 faint floaters, 0 far outliers)"


def test_clean_counts_broken_faint_and_outliers_once_each():
    """Broken Gaussians (NaN mean, zero scale, zero quaternion, inf SH) go first, then floaters with opacity
    strictly below min_opacity (equal is kept), then far outliers among the rest; each is counted once and the
    keep mask removes exactly them."""
    grid = torch.stack(torch.meshgrid(*[torch.arange(6.0)] * 3, indexing="ij"), -1).reshape(-1, 3) * 0.01  # 216
    pts = torch.cat([grid, torch.tensor([[5.0, 5.0, 5.0]])])  # one far outlier, index 216
    gs = gaussians(pts)
    gs.means[0, 0] = float("nan")
    gs.scales[1, 2] = 0.0
    gs.quats[2] = 0.0
    gs.sh[3, 0, 1] = float("inf")
    gs.opacities[4] = 0.005  # faint
    gs.opacities[5] = 0.01  # exactly the threshold: kept
    gs.opacities[216] = 0.005  # faint and far: counted once, as faint
    keep, report = clean(gs, 0.01, 8, 10.0)
    assert (report.broken, report.faint, report.outliers) == (4, 2, 0)
    assert report.kept == 217 - 6 == int(keep.sum())
    assert not keep[:5].any() and bool(keep[5]) and not bool(keep[216])
    gs.opacities[216] = 0.9
    keep, report = clean(gs, 0.01, 8, 10.0)
    assert (report.broken, report.faint, report.outliers) == (4, 1, 1)
    assert not bool(keep[216]) and report.kept == int(keep.sum())


def test_outlier_mask_needs_more_points_than_neighbours():
    """With no neighbours asked for, or no more than k + 1 points, nothing is an outlier."""
    pts = torch.tensor([[0.0, 0, 0], [0.01, 0, 0], [0.02, 0, 0], [9.0, 9, 9]])
    assert not outlier_mask(pts, 0, 1.0).any()
    assert not outlier_mask(pts, 3, 0.1).any()
    assert outlier_mask(pts, 1, 1.0).tolist() == [False, False, False, True]


# ---------------------------------------------------------------------------------------------
# the ground


def scene_with_ground(n_ground=6000, n_object=6000, ground_half=1.0, object_half=0.2, seed=0):
    """A flat sheet of Gaussians at z = 0 (x, y within ±ground_half) and a box object above it (z 0.05–1)."""
    gen = torch.Generator().manual_seed(seed)
    g = torch.zeros(n_ground, 3, dtype=torch.float64)
    g[:, :2] = (torch.rand(n_ground, 2, generator=gen, dtype=torch.float64) * 2 - 1) * ground_half
    o = torch.rand(n_object, 3, generator=gen, dtype=torch.float64)
    o[:, :2] = (o[:, :2] * 2 - 1) * object_half
    o[:, 2] = 0.05 + 0.95 * o[:, 2]
    return torch.cat([g, o])


UP = torch.tensor([0.0, 0.0, 1.0])


def test_ground_top_is_two_bins_above_the_sheet_bin_centre():
    """A flat sheet under an object is found; its top surface lies two histogram bins (1 % of the height range
    each) above the centre of the sheet's bin: between 2 and 3 bins above a zero-thickness sheet, so Gaussians
    lying 2 % of the range above the sheet count as ground and those at 3 % as object."""
    x = scene_with_ground()
    top = find_ground(x, UP)
    assert top is not None
    width = float(torch.quantile(x[:, 2], 0.995) - torch.quantile(x[:, 2], 0.005)) / 100
    assert 2.0 * width < top < 3.0 * width, (top, width)
    lifted = x.clone()
    lifted[:, 2] += 0.3  # translation along up moves the ground with it
    assert find_ground(lifted, UP) == pytest.approx(top + 0.3, abs=1e-9)
    assert find_ground(x, torch.tensor([0.0, 0.0, 5.0])) == pytest.approx(top)  # up need not be unit


def test_ground_needs_an_object_above_it():
    """A sheet with too little above it (under 20 % of the Gaussians) is a flat scan, not a ground; with 30 %
    above it is a ground."""
    assert find_ground(scene_with_ground(n_ground=9000, n_object=1000), UP) is None
    assert find_ground(scene_with_ground(n_ground=7000, n_object=3000), UP) is not None


def test_ground_needs_enough_gaussians_in_its_layer():
    """A sheet holding 5 % of the Gaussians is too small a share to be the ground (8 % needed); 12 % is enough."""
    assert find_ground(scene_with_ground(n_ground=500, n_object=9500), UP) is None
    assert find_ground(scene_with_ground(n_ground=1300, n_object=9500), UP) is not None


def test_ground_must_span_the_scene():
    """A sheet much narrower than the object above it (the bottom face of a wide object) is not the ground."""
    assert find_ground(scene_with_ground(ground_half=0.1, object_half=1.0), UP) is None
    assert find_ground(scene_with_ground(ground_half=1.0, object_half=1.0), UP) is not None


def test_no_ground_without_a_spike():
    """An object whose heights are spread evenly (a solid block, no sheet) has no ground."""
    gen = torch.Generator().manual_seed(1)
    assert find_ground(torch.rand(8000, 3, generator=gen, dtype=torch.float64), UP) is None
    assert find_ground(torch.zeros(100, 3, dtype=torch.float64), UP) is None


def test_the_wide_bottom_of_an_object_is_not_a_ground():
    """A cone standing on its base (heights thinning upward as (1 − z)⁸, the base the widest part, no sheet) has
    its fullest low bin at about 1.7× the mean of the low bins, under the 4× of a spike: it is an object's
    bottom, not a ground (its bottom layer would pass the share, spread and above checks)."""
    gen = torch.Generator().manual_seed(2)
    n = 20000
    z = 1 - torch.rand(n, generator=gen, dtype=torch.float64) ** (1 / 9)  # density 9(1 − z)⁸
    r = (1 - z) * torch.rand(n, generator=gen, dtype=torch.float64).sqrt()
    phi = 2 * math.pi * torch.rand(n, generator=gen, dtype=torch.float64)
    x = torch.stack([r * phi.cos(), r * phi.sin(), z], 1)
    assert find_ground(x, UP) is None


# ---------------------------------------------------------------------------------------------
# export


@pytest.mark.parametrize("k_sim, k_bg", [(4, 1), (1, 4), (9, 4), (4, 4)])
def test_export_keeps_background_colour_whatever_its_sh_degree(tmp_path, k_sim, k_bg):
    """An exported frame with a static background of another SH degree is written at the simulated set's
    degree: the background keeps its DC colour and its first coefficients, missing bands are zero, extra bands
    are dropped; the simulated Gaussians are unchanged."""
    sim = gaussians(torch.rand(3, 3), k=k_sim, seed=1)
    bg = gaussians(torch.rand(5, 3) + 2.0, k=k_bg, seed=2)
    path = export_ply(tmp_path / "sub" / "frame.ply", sim, bg, None)
    back, dropped, fmt = read_gaussians(path)
    assert (dropped, fmt, len(back)) == (0, "ply", 8)
    assert back.sh.shape == (8, k_sim, 3)
    torch.testing.assert_close(back.sh[:3], sim.sh)
    shared = min(k_sim, k_bg)
    torch.testing.assert_close(back.sh[3:, :shared], bg.sh[:, :shared])
    assert bool((back.sh[3:, shared:] == 0).all())
    torch.testing.assert_close(back.means[3:], bg.means)


def test_export_maps_back_to_the_scene_frame(tmp_path):
    """With `to_scene`, the written means are the simulation means under that transform."""
    sim = gaussians(torch.rand(4, 3))
    T = SceneTransform(2.0, torch.eye(3, dtype=torch.float64), torch.tensor([1.0, 0.0, -1.0], dtype=torch.float64))
    back, _, _ = read_gaussians(export_ply(tmp_path / "f.ply", sim, None, T))
    torch.testing.assert_close(back.means, 2.0 * sim.means + torch.tensor([1.0, 0.0, -1.0]))


# ---------------------------------------------------------------------------------------------
# cameras


def opencv_camera(position=(0.0, 0.0, 0.0), height=480, fy=240.0) -> TrainerCamera:
    """A trainer camera looking along +y with +z up (OpenCV axes: x right, y down, z forward)."""
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=torch.float64)
    return TrainerCamera(torch.tensor(position, dtype=torch.float64), R, 300.0, fy, 640, height)


IDENTITY = SceneTransform(1.0, torch.eye(3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64))


@pytest.mark.parametrize("target, look_at", [((0.2, 3.0, 0.5), 3.0), ((0.0, 0.5, 0.1), 0.5), ((0, -2.0, 0), 1e-3)])
def test_trainer_view_looks_along_its_own_axis(target, look_at):
    """The trainer's view keeps its eye and looks along its own axis: the look-at point is the target projected
    on that axis (at least 1 mm ahead, also for a target behind the camera); up is minus the camera's y; the
    field of view is 2·atan(h / 2f_y)."""
    cam = trainer_view(opencv_camera(), IDENTITY, target)
    assert cam.eye == (0.0, 0.0, 0.0)
    assert cam.target == pytest.approx((0.0, look_at, 0.0), abs=1e-12)
    assert cam.up == pytest.approx((0.0, 0.0, 1.0))
    assert cam.fov_deg == pytest.approx(90.0)


def test_trainer_view_goes_through_the_fit():
    """Under a fit (scale 2, offset (1, 1, 1)) the eye moves with the points and the axis turns with the fit's
    rotation (a quarter turn about z takes the view axis +y to −x)."""
    Q = torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    fit = SceneTransform(2.0, Q, torch.ones(3, dtype=torch.float64))
    cam = trainer_view(opencv_camera(position=(0.0, 0.0, 0.0)), fit, (-4.0, 1.0, 1.0))
    assert cam.eye == pytest.approx((1.0, 1.0, 1.0))
    assert cam.target == pytest.approx((-4.0, 1.0, 1.0))


def test_frame_box_sees_the_whole_box_from_minus_y_and_above():
    """The auto camera looks at the box centre from −y, 20° above the horizon, and every corner of the box
    projects inside the field of view, the widest one beyond half of it (not needlessly far)."""
    lo, hi = (0.3, 0.4, 0.2), (0.7, 0.6, 0.5)
    cam = frame_box(lo, hi, 640, 480)
    eye, target = torch.tensor(cam.eye, dtype=torch.float64), torch.tensor(cam.target, dtype=torch.float64)
    assert cam.target == pytest.approx((0.5, 0.5, 0.35))
    d = target - eye
    assert math.degrees(math.atan2(-float(d[2]), float(d[:2].norm()))) == pytest.approx(20.0)
    assert float(d[0]) == pytest.approx(0.0, abs=1e-12) and float(d[1]) > 0
    f = d / d.norm()
    right = torch.linalg.cross(f, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    right = right / right.norm()
    up = torch.linalg.cross(right, f)
    tan_v = math.tan(math.radians(cam.fov_deg) / 2)
    tan_h = tan_v * 640 / 480
    widest = 0.0
    for c in torch.cartesian_prod(*[torch.tensor([a, b], dtype=torch.float64) for a, b in zip(lo, hi)]):
        v = c - eye
        z = float(v @ f)
        u, w = abs(float(v @ right)) / z / tan_h, abs(float(v @ up)) / z / tan_v
        assert z > 0 and u < 1.0 and w < 1.0
        widest = max(widest, u, w)
    assert widest > 0.5


def test_frame_box_leaves_a_15_percent_margin_on_a_wide_box():
    """For a box wider than it is tall, the camera stands just far enough back that the box's nearest corners
    reach 1/1.15 of the half-width of the image: a 15 % margin, no more."""
    lo, hi = (0.0, 0.45, 0.45), (1.0, 0.55, 0.55)
    cam = frame_box(lo, hi, 640, 480)
    eye = torch.tensor(cam.eye, dtype=torch.float64)
    f = torch.tensor(cam.target, dtype=torch.float64) - eye
    f = f / f.norm()
    right = torch.linalg.cross(f, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    right = right / right.norm()
    tan_h = math.tan(math.radians(cam.fov_deg) / 2) * 640 / 480
    corners = torch.cartesian_prod(*[torch.tensor([a, b], dtype=torch.float64) for a, b in zip(lo, hi)])
    v = corners - eye
    u = (v @ right).abs() / (v @ f) / tan_h
    assert float(u.max()) == pytest.approx(1 / 1.15, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# fit


@pytest.mark.parametrize("u", [(0, 0, 1), (0, 0, -1), (0, -1, 0), (1, 2, 3), (-0.3, 0.1, -2)])
def test_rotation_onto_z_is_a_proper_rotation_taking_u_to_z(u):
    """rotation_onto_z(u) is orthonormal with determinant +1 and maps u/|u| onto +z, antiparallel u included."""
    R = rotation_onto_z(torch.tensor(u, dtype=torch.float64))
    n = torch.tensor(u, dtype=torch.float64)
    torch.testing.assert_close(R @ (n / n.norm()), torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    torch.testing.assert_close(R @ R.T, torch.eye(3, dtype=torch.float64))
    assert float(torch.linalg.det(R)) == pytest.approx(1.0)


def test_fit_puts_the_longest_side_on_x_at_the_requested_size():
    """A rod along z, with −y up in the scene (so the rod lies flat): after the fit its longest side is `size`
    metres along x, it is centred at (0.5, 0.5, 0.5), and the scene's up axis is +z, the rod's height along it."""
    gen = torch.Generator().manual_seed(3)
    x = torch.rand(500, 3, generator=gen, dtype=torch.float64) * torch.tensor([0.2, 0.4, 2.0], dtype=torch.float64)
    T = fit_transform(x, torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64), 0.5)
    y = T.points(x)
    ext = y.max(0).values - y.min(0).values
    assert float(ext[0]) == pytest.approx(0.5)
    assert float(ext[2]) == pytest.approx(0.1, rel=0.05) and float(ext[1]) == pytest.approx(0.05, rel=0.05)
    torch.testing.assert_close(0.5 * (y.max(0).values + y.min(0).values), torch.full((3,), 0.5, dtype=torch.float64))
    torch.testing.assert_close(
        T.rotation @ torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64),
        torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64),
    )
    with pytest.raises(SceneError):
        fit_transform(torch.zeros(5, 3, dtype=torch.float64), torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64), 0.5)


def test_roi_box_and_sphere_include_their_boundary():
    """The box and sphere regions of interest keep points on their boundary and drop those just outside."""
    pts = torch.tensor([[0.0, 0, 0], [1.0, 1, 1], [1.01, 0.5, 0.5], [0.5, 0.5, 0.5]])
    cap = CaptureConfig(roi="box", roi_lower=(0.0, 0.0, 0.0), roi_upper=(1.0, 1.0, 1.0))
    assert roi_mask(pts, cap, "s")[0].tolist() == [True, True, False, True]
    cap = CaptureConfig(roi="sphere", roi_center=(0.5, 0.5, 0.5), roi_radius=0.5)
    assert roi_mask(pts, cap, "s")[0].tolist() == [False, False, False, True]
    on = torch.tensor([[1.0, 0.5, 0.5], [0.5, 0.5, 1.01]])
    assert roi_mask(on, cap, "s")[0].tolist() == [True, False]
    with pytest.raises(SceneError, match="roi_radius"):
        roi_mask(pts, CaptureConfig(roi="sphere"), "s")


def test_up_axis_from_cameras_and_config(tmp_path):
    """capture.up wins; otherwise up is minus the mean of the cameras' y axes; without cameras −y is assumed. A
    cameras.json is found beside the PLY or up to three folders above it."""
    cams = [opencv_camera(), opencv_camera()]
    up, why = detect_up(CaptureConfig(), cams)
    torch.testing.assert_close(up, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    assert "+z" in why
    assert detect_up(CaptureConfig(up="+x"), cams)[0].tolist() == [1.0, 0.0, 0.0]
    assert detect_up(CaptureConfig(), [])[0].tolist() == [0.0, -1.0, 0.0]
    deep = tmp_path / "a" / "b" / "c"
    deep.mkdir(parents=True)
    ply = deep / "p.ply"
    assert find_cameras_json(ply, None) is None
    (tmp_path / "a" / "cameras.json").write_text("[]")
    assert find_cameras_json(ply, None) == tmp_path / "a" / "cameras.json"
    (tmp_path / "cameras.json").write_text("[]")
    (tmp_path / "a" / "cameras.json").unlink()
    assert find_cameras_json(ply, None) == tmp_path / "cameras.json"
    with pytest.raises(SceneError, match="non-empty list of views"):
        read_cameras(tmp_path / "cameras.json")


# ---------------------------------------------------------------------------------------------
# resolution and the starter file


def cube_surface(spacing=0.004):
    """Gaussians on the faces of the cube [0.45, 0.55]³: a thick object (its thin parts are its whole 0.1 m width,
    5 cells at the coarsest grid of 0.5 m / 12), small so that the probe's voxels stay few."""
    g = torch.arange(0.45, 0.55 + 1e-9, spacing)
    u, v = [a.flatten() for a in torch.meshgrid(g, g, indexing="ij")]
    faces = []
    for axis in range(3):
        for side in (0.45, 0.55):
            p = torch.empty(len(u), 3)
            others = [a for a in range(3) if a != axis]
            p[:, others[0]], p[:, others[1]], p[:, axis] = u, v, side
            faces.append(p)
    return gaussians(torch.cat(faces), scale=0.6 * spacing)


@pytest.mark.parametrize(
    "device, quality, cells",
    [("cpu", "draft", 12), ("cpu", "default", 20), ("cpu", "fine", 32), ("cuda:0", "draft", 32),
     ("cuda:0", "default", 48), ("cuda:0", "fine", 96)],
)  # fmt: skip
def test_thick_object_gets_the_fewest_cells_of_its_quality(monkeypatch, device, quality, cells):
    """A thick object needs no fine grid, so it gets the quality's fewest cells across on its device (CPU:
    12 / 20 / 32, GPU: 32 / 48 / 96 for draft / default / fine), Δx = size / cells. The probe's measurement is
    given (thin parts 0.1 m, 0.8 % solid: a 0.1 m cube in the 0.5 m size cube), so only the budget is tested."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.1, 0.008))
    res = choose(cube_surface(0.02), CaptureConfig(quality=quality), device)
    assert res.cells == cells
    assert res.dx == pytest.approx(0.5 / cells)
    assert (
        res.budget
        == {"cpu": {"draft": 8_000, "default": 30_000, "fine": 80_000}}.get(
            device, {"draft": 150_000, "default": 600_000, "fine": 2_000_000}
        )[quality]
    )


@pytest.mark.slow  # 0.5–3 s: the probe voxelizes the cube
def test_a_measured_thick_cube_gets_the_gpu_default_floor():
    """Measured by the probe (no stand-in), a 0.1 m cube gets 48 cells across under the GPU's default quality:
    its thin parts (the whole cube) would need only 10."""
    res = choose(cube_surface(), CaptureConfig(), "cuda:0")
    assert res.thin == pytest.approx(0.1, rel=0.1)
    assert res.cells == 48


def test_doc_comments_fit_a_100_column_editor(monkeypatch):
    """The starter TOML's comment lines are at most 100 characters ('# ' + 98), wrapped at word boundaries
    without losing a word, even when a paragraph's first two words make exactly 99 characters."""
    doc = "a" * 49 + " " + "b" * 49 + " " + " ".join(f"w{i}" for i in range(60))
    monkeypatch.setattr(starter, "field_docs", lambda: {("SceneConfig", "name"): doc, ("SimConfig", "dx"): doc})
    text = starter.commented('name = "x"\n\n[sim]\ndx = 0.01\n')
    comments = [line for line in text.splitlines() if line.startswith("#")]
    assert comments and max(len(line) for line in comments) <= 100
    first_block = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        first_block.append(line[2:])
    assert " ".join(first_block).split() == doc.split()
    assert text.splitlines()[len(first_block)] == 'name = "x"'
