"""Hand-written bug campaign, round three: what the renderer draws of a simulated capture (`render.crack_faces`,
`render.camera`, `capture.transform`), each rule against a hand computation.

- A crack face is the surface between two fragments: a particle without a fragment (id −1, e.g. not yet
  labelled) is no other fragment, so a Gaussian beside unlabelled particles keeps its rest covariance Σ⁰; beside a
  particle of another fragment its extent across the bisector is shrunk to the distance d, σ_n → max(d/2σ_n,
  S_MIN)·σ_n.
- A run's camera orbits by orbit_degrees·k/frames at frame k (frame 0 the configured eye, the last frame k = frames
  the whole orbit), turning counter-clockwise about `up` through the target.
"""

import math

import pytest
import torch

from fracture_gs.render.crack_faces import S_MIN, CrackFaces


def _lattice():
    """8 × 3 × 3 particles 1 cm apart (x = 0 … 7 cm), each carrying an isotropic Gaussian of σ = 1 cm."""
    axes = [torch.arange(8) * 0.01, torch.arange(3) * 0.01, torch.arange(3) * 0.01]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).double()  # float32 steps: rtol 1e-6
    cov0 = torch.eye(3, dtype=torch.float64).expand(len(x), 3, 3) * 1e-4
    return x, cov0.contiguous()


def test_unlabelled_particles_are_no_crack_and_another_fragment_is():
    """Columns x ≤ 3 cm are fragment 0, x ≥ 4 cm unlabelled (−1): nothing is trimmed, Σ⁰ comes back as it was.
    With x ≥ 4 cm fragment 1 the two columns beside the cut (x = 3 and 4 cm) are trimmed along x to
    max(0.5 cm / 2 cm, S_MIN)·σ = σ/4 and keep σ across it; every other Gaussian keeps Σ⁰."""
    x, cov0 = _lattice()
    faces = CrackFaces(x, cov0, x, None)
    frag = torch.where(x[:, 0] < 0.035, 0, -1).to(torch.int32)
    assert torch.equal(faces.trimmed(frag), cov0)
    assert faces.trimmed_count == 0
    frag = torch.where(x[:, 0] < 0.035, 0, 1).to(torch.int32)
    out = faces.trimmed(frag)
    beside = (x[:, 0] - 0.035).abs() < 0.006
    sx = out[:, 0, 0].sqrt()
    want = max(0.005 / 0.02, S_MIN) * 0.01
    torch.testing.assert_close(sx[beside], torch.full_like(sx[beside], want), rtol=1e-6, atol=0.0)
    torch.testing.assert_close(out[beside][:, 1, 1], cov0[beside][:, 1, 1], rtol=1e-9, atol=0.0)
    assert torch.equal(out[~beside], cov0[~beside])
    assert faces.trimmed_count == int(beside.sum())


@pytest.mark.parametrize("frames", [1, 4, 10])
def test_a_frames_camera_has_turned_by_its_share_of_the_orbit_the_last_frame_the_whole_of_it(frames):
    """render.camera eye (1.5, 0.5, 0.8), target (0.5, 0.5, 0.3), up +z, orbit_degrees = 90: frame k of `frames`
    sits at angle 90°·k/frames about the vertical through the target, counter-clockwise seen from above (Rodrigues):
    eye = target + (cos θ, sin θ, 0.5); frame 0 at the configured eye, the last frame (k = frames) at (0.5, 1.5, 0.8).
    The camera looks at the target and keeps the image size."""
    from fracture_gs.config import SceneConfig
    from fracture_gs.render.camera import frame_camera

    cfg = SceneConfig()
    cfg.frames = frames
    cfg.render.width, cfg.render.height = 64, 48
    cam = cfg.render.camera
    cam.eye, cam.target, cam.up, cam.orbit_degrees = (1.5, 0.5, 0.8), (0.5, 0.5, 0.3), (0.0, 0.0, 1.0), 90.0
    for k in sorted({0, frames // 2, frames}):
        c = frame_camera(cfg, k)
        th = math.radians(90.0 * k / frames)
        want = torch.tensor([0.5 + math.cos(th), 0.5 + math.sin(th), 0.8], dtype=c.campos.dtype)
        # the view matrix is float32: −Rᵀt rounds to a float32 ulp or two of the eye (BLAS kernels differ by CPU); a
        # wrong share of the orbit (e.g. k/(frames + 1)) moves the eye by centimetres
        torch.testing.assert_close(c.campos, want, rtol=0, atol=1e-6)
        uv, _ = c.project(torch.tensor([[0.5, 0.5, 0.3]], dtype=c.campos.dtype))
        torch.testing.assert_close(uv[0], torch.tensor([32.0, 24.0], dtype=uv.dtype), rtol=0, atol=1e-6)
        assert (c.width, c.height) == (64, 48)
