"""`metrics.stringing`: the mean over band particles of ln(σ_max / σ_min) of F, how far the band is drawn out.

A rotated uniform scaling has ratio 1 (ln 1 = 0), whatever the rotation; diag(2, 1, ½) has ratio 4; only the
listed band particles count; no band particle reads 0."""

import math

import pytest
import torch

from fracture_gs.sim.diagnostics.metrics import stringing


def _rotation(angle: float) -> torch.Tensor:
    c, s = math.cos(angle), math.sin(angle)
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)


def test_stringing_is_the_band_mean_of_the_log_stretch_ratio():
    """Band particles 0 (diag(2, 1, ½): ln 4) and 2 (3× a rotation: ln 1): mean ln 4 / 2 = ln 2; particle 1 (diag(100,
    1, 1), not in the band) does not count; a rotated stretch R·diag(2, 1, ½)·Rᵀ reads ln 4 like the unrotated."""
    R = _rotation(0.7)
    F = torch.stack(
        [torch.diag(torch.tensor([2.0, 1.0, 0.5], dtype=torch.float64)), torch.diag(torch.tensor([100.0, 1, 1])), 3 * R]
    ).float()
    assert float(stringing(F, torch.tensor([0, 2]))) == pytest.approx(math.log(2.0), rel=1e-6)
    turned = (R @ torch.diag(torch.tensor([2.0, 1.0, 0.5], dtype=torch.float64)) @ R.T)[None].float()
    assert float(stringing(turned, torch.tensor([0]))) == pytest.approx(math.log(4.0), rel=1e-6)
    assert float(stringing(F, torch.tensor([], dtype=torch.long))) == 0.0
