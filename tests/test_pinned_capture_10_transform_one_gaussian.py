"""Pinned rule of the SH rotation (`capture.transform.rotate_sh`), round ten: a set of one Gaussian is rotated
like any other. Only degree 0 (colour alone, the same from every direction) and an empty set come back as
copies; a single Gaussian of degree 1–3 gets coefficients whose radiance at d is the original's at Rᵀd, with
one rotation for the set or one for the Gaussian. A scene transform of a one-Gaussian set therefore turns its
view-dependent colour with it.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.transform import SceneTransform, rotate_sh
from fracture_gs.io.gaussian_set import GaussianSet
from fracture_gs.render.gaussians import sh_basis

pytestmark = pytest.mark.usefixtures("one_thread")

F64 = torch.float64


def turn_z(angle: float) -> torch.Tensor:  # [3, 3], a rotation by `angle` about +z
    c, s = math.cos(angle), math.sin(angle)
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=F64)


def directions(n: int = 200, seed: int = 5) -> torch.Tensor:  # [n, 3] random unit vectors
    d = torch.randn(n, 3, generator=torch.Generator().manual_seed(seed), dtype=F64)
    return d / d.norm(dim=1, keepdim=True)


@pytest.mark.parametrize("degree", [1, 2, 3])
@pytest.mark.parametrize("per_gaussian", [False, True])
def test_one_gaussian_is_rotated(degree, per_gaussian):
    """One Gaussian with random coefficients of degree 1–3, turned 90° about z (R [3, 3] or [1, 3, 3]): its
    rotated radiance at 200 directions d equals the original at Rᵀd to 1e-13, and the coefficients change."""
    K = (degree + 1) ** 2
    sh = torch.randn(1, K, 3, generator=torch.Generator().manual_seed(degree), dtype=F64)
    R = turn_z(math.pi / 2)
    out = rotate_sh(sh, R[None] if per_gaussian else R)
    d = directions()
    lhs = sh_basis(d, degree) @ out[0]  # [200, 3]
    rhs = sh_basis(d @ R, degree) @ sh[0]  # (d @ R)_i = (Rᵀ d)_i
    assert float((lhs - rhs).abs().max()) < 1e-13
    assert float((out - sh).abs().max()) > 0.1


def test_a_one_gaussian_scene_turns_its_view_dependent_colour():
    """SceneTransform.gaussians on a single float32 Gaussian of degree 1 whose radiance grows along +x (the
    linear term of x only): after a 90° turn about z it grows along +y, so the colour seen from +y is the one the
    original showed from +x, and the colour from +x is the one it showed from −y."""
    sh = torch.zeros(1, 4, 3)
    ex = torch.tensor([[1.0, 0.0, 0.0]], dtype=F64)
    k = int(sh_basis(ex, 1)[0].abs().argmax())  # the degree-1 coefficient that reads x
    sh[0, k] = torch.tensor([0.3, 0.2, 0.1])
    quats = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    gs = GaussianSet(torch.zeros(1, 3), quats, torch.full((1, 3), 0.01), torch.full((1,), 0.9), sh)
    moved = SceneTransform(1.0, turn_z(math.pi / 2), torch.zeros(3, dtype=F64)).gaussians(gs)

    def colour(g: GaussianSet, d) -> torch.Tensor:  # [3]
        return sh_basis(torch.tensor([d], dtype=F64), 1)[0] @ g.sh[0].double()

    assert torch.allclose(colour(moved, (0.0, 1.0, 0.0)), colour(gs, (1.0, 0.0, 0.0)), atol=1e-6, rtol=0)
    assert torch.allclose(colour(moved, (1.0, 0.0, 0.0)), colour(gs, (0.0, -1.0, 0.0)), atol=1e-6, rtol=0)
    assert float((colour(moved, (1.0, 0.0, 0.0)) - colour(gs, (1.0, 0.0, 0.0))).abs().max()) > 0.1
