"""Hand-written bug campaign, round two: cameras and the per-frame Gaussian update (`capture.camera`,
`render.camera`, `render.gaussians`), each rule against hand values.

- `intrinsics`: the principal point is the image centre, (W/2, H/2) — on a wide image too — so the camera's
  target lands at pixel (W/2, H/2).
- `trainer_view`: the vertical field of view is 2 atan(H / 2 f_y), from the image height and the vertical focal
  length (not the width and f_x of a non-square sensor).
- `frame_box`: the eye sits d = max(a/tan θ_h, u/tan θ_v) + depth from the box centre, with a = 1.15 h_x,
  u = 1.15 (h_z cos e + h_y sin e) and depth = h_y cos e + h_z sin e (the box's extent towards the camera, both
  terms): for the cube of half-side 1 at e = 20°, fov 40°, a square image, d = 5.3314.
- `exposed_interior_colors`: the colour of the nearest surface Gaussian, whichever chunk of the surface it is in.
- `limit_stretch`: every principal stretch ends in [1/s_max, s_max], a compression as well as a stretch.
"""

import math

import torch

from fracture_gs.capture.camera import frame_box, trainer_view
from fracture_gs.capture.fit import TrainerCamera
from fracture_gs.capture.transform import SceneTransform
from fracture_gs.render.camera import look_at
from fracture_gs.render.gaussians import exposed_interior_colors, limit_stretch


def test_the_target_lands_on_the_image_centre_of_a_wide_image():
    """A 320×200 camera looking at the origin: K's principal point is (160, 100) and the origin projects there."""
    cam = look_at((0.0, -2.0, 0.5), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0, 320, 200)
    assert cam.K[0, 2].item() == 160.0 and cam.K[1, 2].item() == 100.0
    uv, depth = cam.project(torch.zeros(1, 3))
    assert torch.allclose(uv, torch.tensor([[160.0, 100.0]]), atol=1e-4) and float(depth[0]) > 0


def test_a_trainer_view_takes_its_vertical_fov_from_the_height_and_fy():
    """A 400×300 view with f_x = 500, f_y = 250 (identity transform): fov = 2 atan(300 / 500) = 61.93°, not
    2 atan(400 / 1000) = 43.6°."""
    cam = TrainerCamera(torch.zeros(3, dtype=torch.float64), torch.eye(3, dtype=torch.float64), 500.0, 250.0, 400, 300)
    fit = SceneTransform(1.0, torch.eye(3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64))
    view = trainer_view(cam, fit, (0.0, 0.0, 2.0))
    assert math.isclose(view.fov_deg, math.degrees(2 * math.atan(0.6)), rel_tol=1e-12)


def test_frame_box_puts_the_eye_at_the_hand_distance():
    """Cube [−1, 1]³, 256×256, fov 40°, elevation 20°: eye = d (0, −cos 20°, sin 20°) with d = 5.3314 (by hand:
    u = 1.15 (cos 20° + sin 20°) = 1.4739, u / tan 20° = 4.0496, depth = cos 20° + sin 20° = 1.2817)."""
    cam = frame_box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0), 256, 256)
    e = math.radians(20.0)
    eye = torch.tensor(cam.eye)
    d = float(eye.norm())
    assert abs(d - 5.3314) < 1e-3
    assert torch.allclose(eye / d, torch.tensor([0.0, -math.cos(e), math.sin(e)]), atol=1e-6)
    assert cam.target == (0.0, 0.0, 0.0)


def test_interior_colours_come_from_the_nearest_surface_gaussian_in_any_chunk():
    """Ten surface Gaussians on the x axis (x = 0 … 9, colour = index), chunks of 4: interior points near x = 7.1,
    2.2 and 9.4 take colours 7, 2 and 9."""
    surface = torch.stack([torch.arange(10.0), torch.zeros(10), torch.zeros(10)], 1)
    colors = torch.arange(10.0)[:, None]
    interior = torch.tensor([[7.1, 0.1, 0.0], [2.2, 0.0, 0.1], [9.4, 0.0, 0.0]])
    got = exposed_interior_colors(interior, surface, colors, chunk=4)
    assert got[:, 0].tolist() == [7.0, 2.0, 9.0]


def test_limit_stretch_clamps_compressions_and_stretches_to_the_band():
    """s_max = 1.25: F = diag(1/1.4, 1, 1) → diag(0.8, 1, 1); diag(1, 1.4, 1) → diag(1, 1.25, 1); diag(1, 1, 1.1)
    (inside the band) stays as it is."""
    F = torch.stack([torch.diag(torch.tensor(d)) for d in ([1 / 1.4, 1.0, 1.0], [1.0, 1.4, 1.0], [1.0, 1.0, 1.1])])
    out = limit_stretch(F, 1.25)
    want = torch.stack([torch.diag(torch.tensor(d)) for d in ([0.8, 1.0, 1.0], [1.0, 1.25, 1.0], [1.0, 1.0, 1.1])])
    assert torch.allclose(out, want, atol=1e-6)
