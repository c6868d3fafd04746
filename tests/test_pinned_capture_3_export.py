"""Pinned rules of splat export with a static background (`capture.export`), round three: the background's SH
coefficients are brought to the simulated set's count for every pair of degrees 0–3 (kept where both have a
coefficient, zero where only the simulated set has one, dropped where only the background has one), in the
file a user opens as in the padding helper.

Unit-level calls on a few Gaussians; one small PLY per case.
"""

from __future__ import annotations

import itertools

import pytest
import torch

from fracture_gs.capture.export import _pad_sh, export_ply
from fracture_gs.io.formats import read_gaussians
from fracture_gs.io.gaussian_set import GaussianSet

COUNTS = (1, 4, 9, 16)  # SH coefficients of degrees 0, 1, 2, 3


@pytest.mark.parametrize("k, have", list(itertools.product(COUNTS, COUNTS)))
def test_background_sh_is_cut_or_zero_padded_to_the_simulated_count(k, have):
    """[N, have, 3] → [N, k, 3]: the first min(k, have) coefficients as they were, then zeros; same dtype."""
    sh = torch.randn(5, have, 3, generator=torch.Generator().manual_seed(k * 17 + have), dtype=torch.float64)
    out = _pad_sh(sh, k)
    assert out.shape == (5, k, 3) and out.dtype == torch.float64
    m = min(k, have)
    assert torch.equal(out[:, :m], sh[:, :m])
    assert bool((out[:, m:] == 0).all())


def gaussians(n, k, offset, seed) -> GaussianSet:
    g = torch.Generator().manual_seed(seed)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    means = torch.rand(n, 3, generator=g) + offset
    return GaussianSet(means, quats, torch.full((n, 3), 0.01), torch.full((n,), 0.8), torch.randn(n, k, 3, generator=g))


@pytest.mark.parametrize("k_sim, k_bg", [(4, 16), (9, 16), (4, 9), (16, 9)])
def test_exported_background_of_a_higher_degree_keeps_its_lower_bands(tmp_path, k_sim, k_bg):
    """A frame simulated at degree 1 or 2 exported with a degree-2 or 3 background (the background of a full
    capture often keeps more bands) is written at the simulated degree, the background's bands up to it
    intact; and a degree-3 frame pads a degree-2 background with zeros."""
    sim, bg = gaussians(3, k_sim, 0.0, 1), gaussians(4, k_bg, 2.0, 2)
    back, dropped, _ = read_gaussians(export_ply(tmp_path / "f.ply", sim, bg, None))
    assert dropped == 0 and back.sh.shape == (7, k_sim, 3)
    m = min(k_sim, k_bg)
    assert torch.allclose(back.sh[3:, :m], bg.sh[:, :m], atol=1e-6)
    assert bool((back.sh[3:, m:] == 0).all())
    assert torch.allclose(back.sh[:3], sim.sh, atol=1e-6)
