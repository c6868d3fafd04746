"""Pinned rules of `capture.fit.config_rotation`, round five: capture.rotation as the proper rotation the fit
uses. Absent, there is none (the fit finds one). Exactly orthonormal (within 1e-12, as a resolved config
writes it back), it is used bit for bit, so a rerun of a written config fits the same. Written with a few
digits (validation lets |RᵀR − I| up to 1e-3 through), it is replaced by the nearest rotation, the orthonormal
factor of its polar decomposition: for R = Q·(I + εS) with Q a rotation and S symmetric, that is Q.
"""

from __future__ import annotations

import math

import torch

from fracture_gs.capture.fit import config_rotation
from fracture_gs.config import CaptureConfig

F64 = torch.float64
EYE = torch.eye(3, dtype=F64)


def turn(a: float, b: float) -> torch.Tensor:  # [3, 3]
    """A rotation by a about z, then b about x."""
    rz = torch.tensor([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]], dtype=F64)
    rx = torch.tensor([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]], dtype=F64)
    return rx @ rz


def of(rotation) -> torch.Tensor | None:
    cap = CaptureConfig()
    cap.rotation = None if rotation is None else tuple(tuple(float(v) for v in row) for row in rotation.tolist())
    return config_rotation(cap)


def test_no_rotation_given_is_none():
    """capture.rotation unset: no rotation is imposed."""
    assert of(None) is None


def test_an_exact_rotation_is_used_bit_for_bit():
    """A rotation orthonormal to float64 rounding (|RᵀR − I| ~ 1e-16) comes back exactly as written, float64;
    a rotation taken through an SVD would differ in its last bits."""
    for R in (turn(0.3, -1.2), turn(2.0, 0.7), EYE):
        assert float((R.T @ R - EYE).abs().max()) < 1e-12
        got = of(R)
        assert got.dtype == F64 and torch.equal(got, R)


def test_a_rotation_written_with_few_digits_becomes_the_nearest_rotation():
    """R = Q·(I + εS), a rotation Q stretched by a symmetric 1e-4 (what four written digits do): the result is
    Q to 1e-14, exactly orthonormal with determinant +1; R itself was 2e-4 off orthonormal."""
    Q = turn(0.9, 0.4)
    S = torch.tensor([[1.0, 0.5, -0.3], [0.5, -2.0, 0.2], [-0.3, 0.2, 0.7]], dtype=F64)
    R = Q @ (EYE + 1e-4 * S)
    assert float((R.T @ R - EYE).abs().max()) > 1e-4
    got = of(R)
    assert float((got - Q).abs().max()) < 1e-14
    assert float((got.T @ got - EYE).abs().max()) < 1e-14
    assert abs(float(torch.linalg.det(got)) - 1.0) < 1e-14


def test_four_digit_entries_of_a_quarter_turn_become_the_quarter_turn():
    """0.7071 written for cos 45° and sin 45° (off by 7e-6): the rotation used is the exact 45° turn about z."""
    c = 0.7071
    R = torch.tensor([[c, -c, 0.0], [c, c, 0.0], [0.0, 0.0, 1.0]], dtype=F64)
    got = of(R)
    s = math.sqrt(0.5)
    want = torch.tensor([[s, -s, 0.0], [s, s, 0.0], [0.0, 0.0, 1.0]], dtype=F64)
    assert float((got - want).abs().max()) < 1e-15
