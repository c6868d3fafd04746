"""Pinned rule of `capture.rotation` (`fracture_gs.io.config.validate`): an orthonormal matrix is accepted exactly
when it is a proper rotation (determinant +1) and refused as a reflection (determinant -1) otherwise, whichever
entries are zero.

The expected determinant never comes from the code under test: for the 48 signed permutation matrices it is the
permutation's sign times the product of the signs (counted by inversions), for the generic rotations it is +1 by
construction (a product of three axis rotations) and -1 once one row is negated. A signed permutation has one
non-zero entry per row, so every one of the six cofactor products is the only term of the determinant for some of
them: a wrong index in any term flips or zeroes the determinant of one of these matrices.

Unit-level: `config_from_dict` only.
"""

from __future__ import annotations

import itertools
import math

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict


def _config(rotation):
    return config_from_dict(
        {"variants": ["baseline"], "scene": "thing.ply", "capture": {"rotation": rotation}}, source="t.toml"
    )


def _signed_permutations():
    """(matrix, determinant) for every 3×3 matrix with one ±1 per row and column (48 of them)."""
    out = []
    for perm in itertools.permutations(range(3)):
        inversions = sum(1 for i in range(3) for j in range(i + 1, 3) if perm[i] > perm[j])
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = [[0.0] * 3 for _ in range(3)]
            for row, col in enumerate(perm):
                R[row][col] = signs[row]
            out.append((R, (-1) ** inversions * math.prod(signs)))
    return out


def _axis_rotations(a: float, b: float, c: float):
    """Rz(a) · Rx(b) · Ry(c) as nested lists: a proper rotation with no zero entry for generic angles."""

    def mul(A, B):
        return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]

    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    Rz = [[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]]
    Rx = [[1.0, 0.0, 0.0], [0.0, cb, -sb], [0.0, sb, cb]]
    Ry = [[cc, 0.0, sc], [0.0, 1.0, 0.0], [-sc, 0.0, cc]]
    return mul(mul(Rz, Rx), Ry)


def test_every_signed_permutation_is_accepted_iff_its_determinant_is_plus_one():
    """Of the 48 axis permutations with signs, the 24 proper rotations load as written and the 24 reflections are
    refused naming capture.rotation, the matrix, its determinant (-1) and the fix (negate one row)."""
    cases = _signed_permutations()
    assert sorted(d for _, d in cases) == [-1.0] * 24 + [1.0] * 24
    for R, det in cases:
        if det > 0:
            assert [list(r) for r in _config(R).capture.rotation] == R
            continue
        with pytest.raises(ConfigError) as info:
            _config(R)
        assert info.value.field == "capture.rotation"
        assert str(info.value) == (
            f"t.toml: capture.rotation = {R} is a reflection (determinant -1); negate one row to make it a proper "
            "rotation (determinant +1), or remove it (automatic)."
        )


@pytest.mark.parametrize("angles", [(0.3, 0.7, 1.1), (2.0, -0.4, 0.9), (-1.3, 2.6, -2.2)])
def test_a_generic_rotation_loads_and_each_of_its_mirrors_is_a_reflection(angles):
    """A rotation with all nine entries non-zero (every cofactor term counts) loads unchanged; negating any one of
    its rows, or all three, gives determinant -1 and is refused as a reflection naming that determinant."""
    R = _axis_rotations(*angles)
    assert all(abs(v) > 1e-3 for row in R for v in row)
    assert [list(r) for r in _config(R).capture.rotation] == R
    mirrors = [[[-v for v in r] if i == k else r for i, r in enumerate(R)] for k in range(3)]
    mirrors.append([[-v for v in r] for r in R])
    for M in mirrors:
        with pytest.raises(ConfigError) as info:
            _config(M)
        assert info.value.field == "capture.rotation" and "is a reflection (determinant -1);" in str(info.value)
